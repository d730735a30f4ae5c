#pragma once
// The command-line options the DDS subcommands (node, fusion, alert) share, declared once so
// their names, ranges and help read the same in every subcommand, and the wall-time limit the
// services (fusion, alert) run under.
#include <chrono>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "apps/cli_checks.hpp"

namespace dronetrack::apps {

struct DdsOptions {
  std::optional<int> domain;  // --domain: wins over the site's dds.domain_id (resolve_domain)
  std::string identity;       // --identity: DDS Security identity in dds.security.directory
};

// --domain and --identity; `default_identity` says in the help what an unset identity means.
inline void add_dds_options(CLI::App& command, DdsOptions& options,
                            const std::string& default_identity) {
  command.add_option("--domain", options.domain, "DDS domain id (overrides dds.domain_id)")
      ->check(CLI::Range(0, 232));
  command.add_option(
      "--identity", options.identity,
      "DDS Security identity in dds.security.directory (default: " + default_identity + ")");
}

// --duration of a service that otherwise runs until SIGINT/SIGTERM.
inline void add_duration_option(CLI::App& command, double& duration_s) {
  command
      .add_option("--duration", duration_s,
                  "Stop after this many seconds of wall time (default: until SIGINT/SIGTERM)")
      ->check(finite_in(0.0, kMaxDuration_s));
}

// Whether a service given --duration has run its time (never, for 0).
class WallTimeLimit {
 public:
  explicit WallTimeLimit(double duration_s)
      : duration_s_(duration_s), started_(std::chrono::steady_clock::now()) {}
  bool reached() const {
    return duration_s_ > 0.0 &&
           std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count() >
               duration_s_;
  }

 private:
  double duration_s_;
  std::chrono::steady_clock::time_point started_;
};

}  // namespace dronetrack::apps
