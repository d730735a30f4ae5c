#pragma once
// The Prometheus text exposition format (version 0.0.4), written by hand in this one file:
// families of counters, gauges and histograms with their HELP and TYPE lines, names checked,
// label values escaped. What is exposed is decided by the process (apps/metrics.hpp); the
// HTTP server only serves the text (GET /metrics, docs/http_api.md "Metrics").
#include <cstdint>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace dronetrack::http_api {

inline constexpr const char* kMetricsContentType = "text/plain; version=0.0.4; charset=utf-8";

using MetricLabels = std::initializer_list<std::pair<std::string_view, std::string_view>>;

bool valid_metric_name(std::string_view name);  // [a-zA-Z_:][a-zA-Z0-9_:]*
bool valid_label_name(std::string_view name);   // [a-zA-Z_][a-zA-Z0-9_]*, no "__" prefix
// A label value between double quotes: backslash, double quote and newline escaped.
std::string escape_label_value(std::string_view value);
// A sample value: the shortest text that reads back exactly ("12", "0.1"), "+Inf", "-Inf", "NaN".
std::string format_sample_value(double value);

// Observations into fixed buckets. observe() neither allocates nor locks: its owner guards it.
class Histogram {
 public:
  // Upper bounds, finite and strictly increasing; +Inf is implied. Throws std::invalid_argument.
  explicit Histogram(std::vector<double> upper_bounds);
  void observe(double value);  // NaN is ignored
  const std::vector<double>& upper_bounds() const { return upper_bounds_; }
  // Per bucket, not cumulative; one more than upper_bounds (the last: above every bound).
  const std::vector<std::int64_t>& bucket_counts() const { return counts_; }
  std::int64_t count() const { return count_; }
  double sum() const { return sum_; }

 private:
  std::vector<double> upper_bounds_;
  std::vector<std::int64_t> counts_;
  std::int64_t count_ = 0;
  double sum_ = 0.0;
};

// Builds one exposition body. Each family starts with family(); its samples follow.
class MetricsText {
 public:
  enum class Type { counter, gauge, histogram };
  // Throws std::invalid_argument on an invalid name (a programming error, not input).
  void family(std::string_view name, Type type, std::string_view help);
  void sample(std::string_view name, double value, MetricLabels labels = {});
  // The _bucket (cumulative, le="+Inf" last), _sum and _count lines of `histogram`.
  void histogram(std::string_view name, const Histogram& histogram, MetricLabels labels = {});
  const std::string& text() const { return text_; }

 private:
  void write_sample(std::string_view name, std::string_view suffix, MetricLabels labels,
                    std::string_view le, const std::string& value);
  std::string text_;
};

}  // namespace dronetrack::http_api
