#include "http_api/metrics_text.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace dronetrack::http_api {
namespace {

bool name_char(char c, bool first, bool colon) {
  const bool letter = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
  const bool digit = c >= '0' && c <= '9';
  return letter || (colon && c == ':') || (!first && digit);
}

bool valid_name(std::string_view name, bool colon) {
  if (name.empty()) return false;
  for (std::size_t i = 0; i < name.size(); ++i) {
    if (!name_char(name[i], i == 0, colon)) return false;
  }
  return true;
}

void check_name(std::string_view name) {
  if (!valid_metric_name(name)) {
    throw std::invalid_argument("invalid metric name '" + std::string(name) + "'");
  }
}

// HELP text: backslash and newline escaped (quotes are fine there).
std::string escape_help(std::string_view help) {
  std::string out;
  out.reserve(help.size());
  for (char c : help) {
    if (c == '\\') {
      out.append("\\\\");
    } else if (c == '\n') {
      out.append("\\n");
    } else {
      out.push_back(c);
    }
  }
  return out;
}

}  // namespace

bool valid_metric_name(std::string_view name) { return valid_name(name, true); }

bool valid_label_name(std::string_view name) {
  return valid_name(name, false) && name.substr(0, 2) != "__";
}

std::string escape_label_value(std::string_view value) {
  std::string out = escape_help(value);
  std::string quoted;
  quoted.reserve(out.size());
  for (char c : out) {
    if (c == '"') quoted.push_back('\\');
    quoted.push_back(c);
  }
  return quoted;
}

std::string format_sample_value(double value) {
  if (std::isnan(value)) return "NaN";
  if (std::isinf(value)) return value > 0 ? "+Inf" : "-Inf";
  // The shortest text that reads back as the same double ("0.1", not "0.10000000000000001").
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

Histogram::Histogram(std::vector<double> upper_bounds) : upper_bounds_(std::move(upper_bounds)) {
  for (std::size_t i = 0; i < upper_bounds_.size(); ++i) {
    if (!std::isfinite(upper_bounds_[i]) || (i > 0 && upper_bounds_[i] <= upper_bounds_[i - 1])) {
      throw std::invalid_argument("histogram bounds must be finite and strictly increasing");
    }
  }
  counts_.assign(upper_bounds_.size() + 1, 0);
}

void Histogram::observe(double value) {
  if (std::isnan(value)) return;
  std::size_t bucket = 0;
  while (bucket < upper_bounds_.size() && value > upper_bounds_[bucket]) ++bucket;
  ++counts_[bucket];
  ++count_;
  sum_ += value;
}

void MetricsText::family(std::string_view name, Type type, std::string_view help) {
  check_name(name);
  const char* type_name = type == Type::counter ? "counter"
                          : type == Type::gauge ? "gauge"
                                                : "histogram";
  text_.append("# HELP ").append(name).append(" ").append(escape_help(help)).append("\n");
  text_.append("# TYPE ").append(name).append(" ").append(type_name).append("\n");
}

void MetricsText::sample(std::string_view name, double value, MetricLabels labels) {
  write_sample(name, "", labels, "", format_sample_value(value));
}

void MetricsText::histogram(std::string_view name, const Histogram& histogram,
                            MetricLabels labels) {
  std::int64_t cumulative = 0;
  const auto& bounds = histogram.upper_bounds();
  for (std::size_t i = 0; i <= bounds.size(); ++i) {
    cumulative += histogram.bucket_counts()[i];
    const std::string le = i < bounds.size() ? format_sample_value(bounds[i]) : "+Inf";
    write_sample(name, "_bucket", labels, le, std::to_string(cumulative));
  }
  write_sample(name, "_sum", labels, "", format_sample_value(histogram.sum()));
  write_sample(name, "_count", labels, "", std::to_string(histogram.count()));
}

void MetricsText::write_sample(std::string_view name, std::string_view suffix, MetricLabels labels,
                               std::string_view le, const std::string& value) {
  check_name(name);
  text_.append(name).append(suffix);
  if (labels.size() > 0 || !le.empty()) {
    text_.push_back('{');
    bool first = true;
    for (const auto& [label, label_value] : labels) {
      if (!valid_label_name(label)) {
        throw std::invalid_argument("invalid label name '" + std::string(label) + "'");
      }
      if (!first) text_.push_back(',');
      first = false;
      text_.append(label).append("=\"").append(escape_label_value(label_value)).append("\"");
    }
    if (!le.empty()) {
      if (!first) text_.push_back(',');
      text_.append("le=\"").append(le).append("\"");
    }
    text_.push_back('}');
  }
  text_.append(" ").append(value).append("\n");
}

}  // namespace dronetrack::http_api
