#include "config/config_reader.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace dronetrack::config {
namespace {
const nlohmann::json kEmptyObject = nlohmann::json::object();
}  // namespace

std::string format_number(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

std::string printable(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[byte >> 4];
      out += kHex[byte & 0xf];
    } else {
      out += c;
    }
  }
  return out;
}

void Diagnostics::error(const std::string& path, const std::string& what) {
  errors.push_back(printable(path.empty() ? what : path + ": " + what));
}
void Diagnostics::warn(const std::string& path, const std::string& what) {
  // A document with a million unknown keys must not print a million lines.
  ++warning_count;
  if (warnings.size() < kMaxReportedWarnings) {
    warnings.push_back(printable(path.empty() ? what : path + ": " + what));
  } else if (warnings.size() == kMaxReportedWarnings) {
    warnings.push_back("(further warnings not shown)");
  } else {
    warnings.back() =
        "... and " + std::to_string(warning_count - kMaxReportedWarnings) + " more warnings";
  }
}

bool LineReader::next(std::string& line) {
  line.clear();
  std::streambuf* buffer = stream_.rdbuf();
  if (too_long_ || buffer == nullptr) return false;
  for (;;) {
    const int next = buffer->sbumpc();
    if (next == std::char_traits<char>::eof()) {
      if (line.empty()) return false;
      ++number_;
      return true;
    }
    if (next == '\n') {
      ++number_;
      return true;
    }
    if (line.size() >= max_) {
      ++number_;
      too_long_ = true;
      line.clear();
      return false;
    }
    line.push_back(static_cast<char>(next));
  }
}

std::string describe_json_type(const nlohmann::json& node) {
  if (node.is_null()) return "null";
  if (node.is_boolean()) return "a boolean";
  if (node.is_number()) return "a number";
  if (node.is_string()) return "a string";
  if (node.is_array()) return "a list of " + std::to_string(node.size());
  return "an object";
}

ObjectReader::ObjectReader(const nlohmann::json& node, std::string path, Diagnostics& diagnostics)
    : node_(node.is_object() ? node : kEmptyObject),
      path_(std::move(path)),
      diagnostics_(diagnostics) {
  if (!node.is_object()) {
    diagnostics_.error(path_.empty() ? "(top level)" : path_,
                       "expected an object, got " + describe_json_type(node));
    is_object_ = false;
  }
}

ObjectReader::~ObjectReader() {
  if (!is_object_) return;
  for (const auto& item : node_.items()) {
    if (!known_.count(item.key())) diagnostics_.warn(path_of(item.key()), "unknown key, ignored");
  }
}

std::string ObjectReader::path_of(const std::string& key) const {
  return path_.empty() ? key : path_ + "." + key;
}

bool ObjectReader::has(const std::string& key) const { return node_.contains(key); }

const nlohmann::json* ObjectReader::lookup(const std::string& key) {
  known_.insert(key);
  auto found = node_.find(key);
  return found == node_.end() ? nullptr : &*found;
}

std::optional<double> ObjectReader::required_number(const std::string& key, double min,
                                                    double max) {
  const nlohmann::json* value = lookup(key);
  if (!value) {
    diagnostics_.error(path_of(key), "required number is missing");
    return std::nullopt;
  }
  if (!value->is_number()) {
    diagnostics_.error(path_of(key), "expected a number, got " + describe_json_type(*value));
    return std::nullopt;
  }
  const double number_value = value->get<double>();
  if (!std::isfinite(number_value)) {
    diagnostics_.error(path_of(key), "expected a finite number");
    return std::nullopt;
  }
  if (number_value < min || number_value > max) {
    diagnostics_.error(path_of(key), "must be in [" + format_number(min) + ", " +
                                         format_number(max) + "], got " +
                                         format_number(number_value));
    return std::nullopt;
  }
  return number_value;
}

double ObjectReader::number(const std::string& key, double fallback, double min, double max) {
  if (!has(key)) {
    known_.insert(key);
    return fallback;
  }
  return required_number(key, min, max).value_or(fallback);
}

std::optional<int> ObjectReader::optional_integer(const std::string& key, int min, int max) {
  const nlohmann::json* value = lookup(key);
  if (!value) return std::nullopt;
  if (!value->is_number_integer()) {
    diagnostics_.error(path_of(key), "expected an integer, got " + describe_json_type(*value));
    return std::nullopt;
  }
  const auto integer_value = value->get<long long>();
  if (integer_value < min || integer_value > max) {
    diagnostics_.error(path_of(key), "must be in [" + std::to_string(min) + ", " +
                                         std::to_string(max) + "], got " +
                                         std::to_string(integer_value));
    return std::nullopt;
  }
  return static_cast<int>(integer_value);
}

int ObjectReader::integer(const std::string& key, int fallback, int min, int max) {
  return optional_integer(key, min, max).value_or(fallback);
}

bool ObjectReader::boolean(const std::string& key, bool fallback) {
  const nlohmann::json* value = lookup(key);
  if (!value) return fallback;
  if (!value->is_boolean()) {
    diagnostics_.error(path_of(key), "expected true or false, got " + describe_json_type(*value));
    return fallback;
  }
  return value->get<bool>();
}

std::optional<std::string> ObjectReader::required_string(const std::string& key) {
  const nlohmann::json* value = lookup(key);
  if (!value) {
    diagnostics_.error(path_of(key), "required string is missing");
    return std::nullopt;
  }
  if (!value->is_string()) {
    diagnostics_.error(path_of(key), "expected a string, got " + describe_json_type(*value));
    return std::nullopt;
  }
  return value->get<std::string>();
}

std::string ObjectReader::string(const std::string& key, const std::string& fallback) {
  if (!has(key)) {
    known_.insert(key);
    return fallback;
  }
  return required_string(key).value_or(fallback);
}

std::string ObjectReader::choice(const std::string& key, const std::string& fallback,
                                 const std::vector<std::string>& choices) {
  const std::string value = string(key, fallback);
  for (const auto& option : choices) {
    if (option == value) return value;
  }
  std::string list;
  for (const auto& option : choices) list += (list.empty() ? "" : ", ") + option;
  diagnostics_.error(path_of(key), "unknown value \"" + value + "\", expected one of: " + list);
  return fallback;
}

std::optional<Eigen::Vector3d> read_vector3(const nlohmann::json& node, const std::string& path,
                                            Diagnostics& diagnostics) {
  if (!node.is_array() || node.size() != 3) {
    diagnostics.error(path, "expected 3 numbers, got " + describe_json_type(node));
    return std::nullopt;
  }
  Eigen::Vector3d out;
  for (int i = 0; i < 3; ++i) {
    const auto& element = node[static_cast<std::size_t>(i)];
    if (!element.is_number()) {
      diagnostics.error(path + "[" + std::to_string(i) + "]",
                        "expected a number, got " + describe_json_type(element));
      return std::nullopt;
    }
    out[i] = element.get<double>();
    if (!std::isfinite(out[i])) {
      diagnostics.error(path + "[" + std::to_string(i) + "]", "expected a finite number");
      return std::nullopt;
    }
  }
  return out;
}

std::optional<Eigen::Vector3d> ObjectReader::vector3(const std::string& key, bool required) {
  const nlohmann::json* value = lookup(key);
  if (!value) {
    if (required) diagnostics_.error(path_of(key), "required [x, y, z] is missing");
    return std::nullopt;
  }
  return read_vector3(*value, path_of(key), diagnostics_);
}

std::optional<std::vector<double>> ObjectReader::numbers(const std::string& key, std::size_t size,
                                                         bool required) {
  const nlohmann::json* value = lookup(key);
  if (!value) {
    if (required) diagnostics_.error(path_of(key), "required list of numbers is missing");
    return std::nullopt;
  }
  const bool size_ok = value->is_array() && (size == 0 ? !value->empty() : value->size() == size);
  if (!size_ok) {
    diagnostics_.error(path_of(key), "expected " +
                                         (size == 0 ? std::string("a list of numbers")
                                                    : std::to_string(size) + " numbers") +
                                         ", got " + describe_json_type(*value));
    return std::nullopt;
  }
  std::vector<double> out;
  for (std::size_t i = 0; i < value->size(); ++i) {
    const auto& element = (*value)[i];
    const std::string element_path = path_of(key) + "[" + std::to_string(i) + "]";
    if (!element.is_number() || !std::isfinite(element.get<double>())) {
      diagnostics_.error(element_path,
                         "expected a finite number, got " + describe_json_type(element));
      return std::nullopt;
    }
    out.push_back(element.get<double>());
  }
  return out;
}

bool ObjectReader::for_each(
    const std::string& key, bool required,
    const std::function<void(const nlohmann::json&, const std::string&)>& each) {
  const nlohmann::json* value = lookup(key);
  if (!value) {
    if (required) diagnostics_.error(path_of(key), "required list is missing");
    return !required;
  }
  if (!value->is_array()) {
    diagnostics_.error(path_of(key), "expected a list, got " + describe_json_type(*value));
    return false;
  }
  for (std::size_t i = 0; i < value->size(); ++i) {
    each((*value)[i], path_of(key) + "[" + std::to_string(i) + "]");
  }
  return true;
}

ObjectReader ObjectReader::object(const std::string& key) {
  const nlohmann::json* value = lookup(key);
  return ObjectReader(value ? *value : kEmptyObject, path_of(key), diagnostics_);
}

}  // namespace dronetrack::config
