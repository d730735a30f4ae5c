#pragma once
// Walks a JSON document while remembering the path to each value, so every problem is reported
// as one line naming where it is ("arrays[1].mics_m[2]: expected 3 numbers, got 2"). Problems
// are collected, not thrown, so one run reports them all. Unknown keys become warnings.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <istream>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace dronetrack::config {

struct Diagnostics {
  std::vector<std::string> errors;
  std::vector<std::string> warnings;  // at most kMaxReportedWarnings + 1 (a count of the rest)
  std::size_t warning_count = 0;
  void error(const std::string& path, const std::string& what);
  void warn(const std::string& path, const std::string& what);
};

class ObjectReader {
 public:
  // `node` must outlive the reader. If it is not an object, an error is recorded and every
  // lookup returns its default.
  ObjectReader(const nlohmann::json& node, std::string path, Diagnostics& diagnostics);
  ~ObjectReader();  // reports unknown keys
  ObjectReader(const ObjectReader&) = delete;
  ObjectReader& operator=(const ObjectReader&) = delete;

  bool has(const std::string& key) const;
  std::string path_of(const std::string& key) const;
  const std::string& path() const { return path_; }
  Diagnostics& diagnostics() { return diagnostics_; }

  // Finite number within [min, max]; default when absent.
  double number(const std::string& key, double fallback, double min = -1e300, double max = 1e300);
  std::optional<double> required_number(const std::string& key, double min = -1e300,
                                        double max = 1e300);
  // An integer within [min, max]; default when absent.
  int integer(const std::string& key, int fallback, int min = std::numeric_limits<int>::min(),
              int max = std::numeric_limits<int>::max());
  std::optional<int> optional_integer(const std::string& key, int min, int max);
  bool boolean(const std::string& key, bool fallback);
  std::string string(const std::string& key, const std::string& fallback);
  std::optional<std::string> required_string(const std::string& key);
  // One of `choices`; error lists them.
  std::string choice(const std::string& key, const std::string& fallback,
                     const std::vector<std::string>& choices);
  std::optional<Eigen::Vector3d> vector3(const std::string& key, bool required);
  // A list of numbers of exactly `size` (size 0: any length >= 1).
  std::optional<std::vector<double>> numbers(const std::string& key, std::size_t size,
                                             bool required);
  // Calls `each(element, element_path)` for every element of an array-valued key.
  // Returns false (and records an error) if the key is present but not an array, or missing
  // while required.
  bool for_each(const std::string& key, bool required,
                const std::function<void(const nlohmann::json&, const std::string&)>& each);
  // Nested object; absent key reads as an empty object.
  ObjectReader object(const std::string& key);
  // Marks a key as known without reading it here.
  void accept(const std::string& key) { known_.insert(key); }

 private:
  const nlohmann::json* lookup(const std::string& key);
  const nlohmann::json& node_;
  std::string path_;
  Diagnostics& diagnostics_;
  std::set<std::string> known_;
  bool is_object_ = true;
};

// Input bounds (docs/contract.md): a file or line larger than these is refused before it is read
// into memory, so a hostile or broken input costs a stat, not gigabytes.
inline constexpr std::size_t kMaxConfigBytes = 4u << 20;   // site config, scenario: a few kB
inline constexpr std::size_t kMaxTruthBytes = 512u << 20;  // truth.json: 4-7 MB per scene minute
inline constexpr std::size_t kMaxLineBytes = 64u << 10;    // a DOA/track/alert line: < 1 kB
inline constexpr std::size_t kMaxReportedWarnings = 20;    // then "... and N more"

// Lines of a JSON-lines stream, each at most `max_bytes`; a longer one stops the reader with
// too_long() set (its text is skipped, never held).
class LineReader {
 public:
  LineReader(std::istream& stream, std::size_t max_bytes) : stream_(stream), max_(max_bytes) {}
  bool next(std::string& line);
  int number() const { return number_; }  // of the last line returned (1-based)
  bool too_long() const { return too_long_; }

 private:
  std::istream& stream_;
  std::size_t max_;
  int number_ = 0;
  bool too_long_ = false;
};

// Reads a JSON array of exactly 3 finite numbers at `path`.
std::optional<Eigen::Vector3d> read_vector3(const nlohmann::json& node, const std::string& path,
                                            Diagnostics& diagnostics);
std::string describe_json_type(const nlohmann::json& node);
// `text` with its control characters shown as \xNN: a message quoting a key or a string of
// the input stays one line (a JSON "\n" in a key would otherwise split or forge a line; found
// by fuzz/site_config). Diagnostics applies it to every problem.
std::string printable(const std::string& text);
// A number as an error message shows it (shortest form: 1.5, 0.3, 1e-05).
std::string format_number(double value);

}  // namespace dronetrack::config
