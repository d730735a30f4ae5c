// `replay --doa-in D.jsonl`: DOA JSON lines (SPEC 3.2) read against the perimeter site, then,
// when they span at most a minute, fed to the fusion as the replay does. Properties: the reader
// throws only std::runtime_error (one line: the file and the line at fault), and whatever it
// accepts the fusion digests without a crash.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/doa_file_replay.hpp"
#include "common/log.hpp"
#include "config/site_config.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

// A DOA file may span 24 h (kMaxDoaSpan_s): the fusion ticks through all of it, ~1e6 ticks,
// which is a valid run, not a finding; ten seconds keep the harness near 100 inputs/s.
constexpr double kFusedSpan_s = 10.0;

const dronetrack::config::SiteConfig& site() {
  static const dronetrack::config::SiteConfig loaded = [] {
    std::vector<std::string> warnings;
    dronetrack::config::LoadOptions options;
    options.check_recordings = false;
    return dronetrack::config::load_site_config(DRONETRACK_SOURCE_DIR "/config/site-perimeter.json",
                                                warnings, options);
  }();
  return loaded;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static dronetrack::fuzz::MemoryFile file;
  static const bool quiet = [] {
    dronetrack::log::set_level(dronetrack::log::Level::error);  // one warning per input is noise
    return true;
  }();
  (void)quiet;
  const std::string& path = file.write(data, size);
  std::vector<dronetrack::doa::DoaMeasurement> doas;
  try {
    doas = dronetrack::apps::read_doa_measurements(path, site());
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    if (message.empty() || message.find('\n') != std::string::npos)
      dronetrack::fuzz::fail("DOA reader error is not one line");
    return 0;
  }
  if (doas.empty() || doas.back().time_s - doas.front().time_s > kFusedSpan_s) return 0;
  (void)dronetrack::apps::replay_doas(site(), doas, {});
  return 0;
}
