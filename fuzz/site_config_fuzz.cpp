// Site config (SPEC 3.1) text -> SiteConfig, as `load_site_config` parses it after reading the
// file. Properties: only ConfigError escapes (any other exception aborts the fuzzer), and every
// problem is one non-empty line, as the command line prints it.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "config/config_reader.hpp"
#include "config/site_config.hpp"
#include "fuzz/fuzz_support.hpp"

using dronetrack::fuzz::check_lines;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dronetrack::config;
  // load_site_config refuses a larger file before reading it.
  if (size > kMaxConfigBytes) return 0;
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> warnings;
  LoadOptions options;
  // No file system: recordings and pose files are named, not opened (their readers have their
  // own harnesses).
  options.check_recordings = false;
  options.read_pose_files = false;
  try {
    const SiteConfig site = parse_site_config(text, "/fuzz-site", warnings, options);
    // What every consumer asks first of a site that loaded.
    for (std::size_t i = 0; i < site.arrays.size(); ++i) {
      (void)site.doa_params(i);
      if (site.array_index(site.arrays[i].geometry.id) < 0) dronetrack::fuzz::fail("array id lost");
    }
    (void)site.geometries();
  } catch (const ConfigError& error) {
    if (error.problems().empty()) dronetrack::fuzz::fail("ConfigError without a problem");
    check_lines(error.problems());
  }
  check_lines(warnings);
  return 0;
}
