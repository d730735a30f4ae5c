#pragma once
// Helpers shared by the DDS subcommands (node, fusion, alert): domain id resolution and a log
// that speaks at most once per second per kind of problem. (Stopping: apps/signals.hpp.)
#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "config/site_config.hpp"
#include "dds_idl/dds.hpp"

namespace dronetrack::apps {

// `--domain N` wins over the site's "dds.domain_id". Throws UserError outside 0..232.
int resolve_domain(const config::SiteConfig& site, std::optional<int> flag);

// The DDS Security files of identity `name` in the site's PKI directory, or nothing if the
// site runs plain DDS. Throws UserError if security is on and a file is missing, naming it.
std::optional<dds::SecurityFiles> security_files(const config::SiteConfig& site,
                                                 const std::string& name);

// The site's array ids in config order (index = array index).
std::vector<std::string> array_ids(const config::SiteConfig& site);

// "array N2: 14 samples with NaN ignored" at most once per second per kind, with the count
// accumulated since the last line, so a flood of bad samples cannot flood the log.
class ThrottledWarnings {
 public:
  static constexpr int kKinds = 24;  // Doa and NodeStatus problems (2 x 8) and the engine's
  void count(int kind, const char* what);
  // Emits what is pending regardless of the interval (at shutdown).
  void flush();

 private:
  struct Kind {
    std::int64_t pending = 0;
    std::chrono::steady_clock::time_point last_line{};
    const char* what = "";
  };
  void emit(Kind& kind, std::chrono::steady_clock::time_point now);
  std::array<Kind, kKinds> kinds_{};
};

}  // namespace dronetrack::apps
