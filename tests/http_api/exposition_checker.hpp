#pragma once
// An independent reader of the Prometheus text format (0.0.4) for the tests: every line must be
// a HELP, TYPE or sample line with valid names and escapes; every sample belongs to a family
// declared by a TYPE line before it, families are contiguous, and each histogram's buckets are
// cumulative with le="+Inf" last and equal to its _count. Problems are collected, not thrown.
#include <cmath>
#include <cstdlib>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace dronetrack::test {

struct Exposition {
  // "name" or "name{a=\"x\",b=\"y\"}" (labels as written) -> value.
  std::map<std::string, double> samples;
  std::vector<std::string> problems;
  bool ok() const { return problems.empty(); }
  double value(const std::string& key) const {
    const auto found = samples.find(key);
    return found == samples.end() ? std::nan("") : found->second;
  }
  // Sum over every sample of `name` (any labels).
  double sum(const std::string& name) const {
    double total = 0.0;
    for (const auto& [key, v] : samples) {
      if (key == name || key.rfind(name + "{", 0) == 0) total += v;
    }
    return total;
  }
};

inline bool parse_sample_value(const std::string& text, double& value) {
  if (text == "+Inf" || text == "-Inf" || text == "NaN") {
    value = text == "NaN" ? std::nan("") : (text[0] == '+' ? INFINITY : -INFINITY);
    return true;
  }
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return !text.empty() && end == text.c_str() + text.size();
}

inline Exposition check_exposition(const std::string& text) {
  Exposition out;
  const std::regex help_line("# HELP ([a-zA-Z_:][a-zA-Z0-9_:]*) (.*)");
  const std::regex type_line(
      "# TYPE ([a-zA-Z_:][a-zA-Z0-9_:]*) (counter|gauge|histogram|summary|untyped)");
  // name, optional {labels}, value (no timestamps are written).
  const std::regex sample_line(R"(([a-zA-Z_:][a-zA-Z0-9_:]*)(\{(.*)\})? (\S+))");
  const std::regex label(R"(([a-zA-Z_][a-zA-Z0-9_]*)="((?:[^"\\\n]|\\[\\"n])*)\"(,|$))");
  std::map<std::string, std::string> types;
  std::set<std::string> helped;
  std::set<std::string> finished;  // families another family followed
  std::string current;
  // Histogram series (name + labels without le) -> (le, cumulative count) in order, and count.
  std::map<std::string, std::vector<std::pair<double, double>>> buckets;
  std::map<std::string, double> counts;
  if (!text.empty() && text.back() != '\n')
    out.problems.push_back("body does not end in a newline");
  std::istringstream lines(text);
  std::string line;
  int number = 0;
  const auto fail = [&](const std::string& what) {
    out.problems.push_back("line " + std::to_string(number) + ": " + what + ": " + line);
  };
  const auto enter_family = [&](const std::string& family) {
    if (family == current) return;
    if (finished.count(family)) fail("family " + family + " is not contiguous");
    if (!current.empty()) finished.insert(current);
    current = family;
  };
  while (std::getline(lines, line)) {
    ++number;
    std::smatch m;
    if (line.empty()) continue;
    if (line.rfind("# HELP ", 0) == 0) {
      if (!std::regex_match(line, m, help_line)) {
        fail("malformed HELP");
        continue;
      }
      if (!helped.insert(m[1]).second) fail("second HELP");
      enter_family(m[1]);
      continue;
    }
    if (line.rfind("# TYPE ", 0) == 0) {
      if (!std::regex_match(line, m, type_line)) {
        fail("malformed TYPE");
        continue;
      }
      if (types.count(m[1])) fail("second TYPE");
      enter_family(m[1]);
      types[m[1]] = m[2];
      continue;
    }
    if (line[0] == '#') continue;  // a comment
    if (!std::regex_match(line, m, sample_line)) {
      fail("not a sample line");
      continue;
    }
    const std::string name = m[1];
    std::string family = name;
    std::string suffix;
    for (const char* s : {"_bucket", "_sum", "_count"}) {
      const std::string tail = s;
      if (name.size() > tail.size() &&
          name.compare(name.size() - tail.size(), tail.size(), tail) == 0 &&
          types.count(name.substr(0, name.size() - tail.size())) &&
          types[name.substr(0, name.size() - tail.size())] == "histogram") {
        family = name.substr(0, name.size() - tail.size());
        suffix = tail;
      }
    }
    if (!types.count(family)) {
      fail("sample before its TYPE");
      continue;
    }
    if (types[family] == "histogram" && suffix.empty()) fail("histogram sample without suffix");
    enter_family(family);
    const std::string labels = m[3];
    std::string rest = labels;
    std::string without_le;
    std::string le;
    std::set<std::string> label_names;
    while (!rest.empty()) {
      std::smatch lm;
      if (!std::regex_search(rest, lm, label) || lm.position(0) != 0) {
        fail("malformed labels");
        break;
      }
      if (!label_names.insert(lm[1]).second) fail("repeated label");
      if (lm[1] == "le") {
        le = lm[2];
      } else {
        without_le += lm[1].str() + "=\"" + lm[2].str() + "\";";  // separator-independent
      }
      rest = lm.suffix();
    }
    double value = 0.0;
    if (!parse_sample_value(m[4], value)) {
      fail("bad value");
      continue;
    }
    const std::string key = labels.empty() ? name : name + "{" + labels + "}";
    if (out.samples.count(key)) fail("duplicate series");
    out.samples[key] = value;
    const std::string series = family + "{" + without_le + "}";
    if (suffix == "_bucket") {
      double bound = 0.0;
      if (le.empty() || !parse_sample_value(le, bound)) {
        fail("bucket without a valid le");
        continue;
      }
      auto& list = buckets[series];
      if (!list.empty() && (bound <= list.back().first || value < list.back().second))
        fail("buckets not increasing or not cumulative");
      list.push_back({bound, value});
    } else if (suffix == "_count") {
      counts[series] = value;
    }
  }
  for (const auto& [series, list] : buckets) {
    if (list.empty() || !std::isinf(list.back().first))
      out.problems.push_back(series + ": last bucket is not le=\"+Inf\"");
    else if (!counts.count(series) || counts[series] != list.back().second)
      out.problems.push_back(series + ": +Inf bucket differs from _count");
  }
  return out;
}

}  // namespace dronetrack::test
