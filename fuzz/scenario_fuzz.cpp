// Scenario file text -> Scenario, as `load_scenario` parses it after reading the file (sim
// --scenario, docs/scenarios.md). Properties: only ConfigError escapes the parser, and every
// problem is one non-empty line.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/config_reader.hpp"
#include "config/site_config.hpp"
#include "fuzz/fuzz_support.hpp"
#include "sim/scenario.hpp"

using dronetrack::fuzz::check_lines;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using dronetrack::config::ConfigError;
  if (size > dronetrack::config::kMaxConfigBytes) return 0;  // refused before it is read
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(data, data + size);
  } catch (const nlohmann::json::exception&) {
    return 0;  // load_scenario: "invalid JSON: ..." (nlohmann's own message)
  }
  std::vector<std::string> warnings;
  try {
    const dronetrack::sim::Scenario scenario =
        dronetrack::sim::parse_scenario(document, "/fuzz-scenario", warnings);
    (void)scenario;
  } catch (const ConfigError& error) {
    if (error.problems().empty()) dronetrack::fuzz::fail("ConfigError without a problem");
    check_lines(error.problems());
  }
  check_lines(warnings);
  return 0;
}
