// `dronetrack sim SCENARIO.json --out DIR`: synthesise a scene (SPEC 3.3, docs/scenarios.md).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/signals.hpp"
#include "common/log.hpp"
#include "sim/render.hpp"
#include "sim/scenario.hpp"

namespace dronetrack::apps {

namespace {

struct SimOptions {
  std::string scenario;
  std::string out_dir;
  double duration_s = 0.0;  // 0: as in the scenario
};

int run_sim(const SimOptions& options) {
  std::vector<std::string> warnings;
  sim::Scenario scenario = sim::load_scenario(options.scenario, warnings);
  for (const auto& warning : warnings) log::warn(warning);
  if (options.duration_s > 0.0) {
    scenario.duration_s = options.duration_s;
    for (auto& end_s : scenario.recording_end_s) {
      if (end_s >= scenario.duration_s) end_s = 0.0;
    }
  }
  const auto started = std::chrono::steady_clock::now();
  const sim::WrittenScene written =
      sim::write_scene(scenario, options.out_dir, &install_stop_handlers());
  if (written.interrupted) {
    log::error("sim: interrupted by ", stop_signal_name(), "; nothing written to ",
               options.out_dir);
    return interrupted_exit_code();
  }
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  std::printf("wrote %s\n", written.site.string().c_str());
  for (const auto& recording : written.recordings) {
    std::printf("wrote %s\n", recording.string().c_str());
  }
  for (const auto& pose : written.poses) std::printf("wrote %s\n", pose.string().c_str());
  if (!written.reference.empty()) std::printf("wrote %s\n", written.reference.string().c_str());
  std::printf("wrote %s\n", written.truth.string().c_str());
  std::printf("%.1f s of audio, %zu arrays, %.0f Hz, rendered in %.2f s%s\n", scenario.duration_s,
              scenario.site.arrays.size(), scenario.sample_rate_hz, elapsed_s,
              written.scale < 1.0 ? " (scaled down to avoid clipping)" : "");
  return 0;
}

}  // namespace

void register_sim(CLI::App& root, CommandTable& table) {
  auto options = std::make_shared<SimOptions>();
  auto* command = root.add_subcommand(
      "sim", "Synthesise a scene: DIR/site.json, one WAV per array, DIR/truth.json");
  command->add_option("scenario", options->scenario, "Scenario file (docs/scenarios.md)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--out", options->out_dir, "Output directory (created)")->required();
  command
      ->add_option("--duration-s", options->duration_s,
                   "Render only the first N seconds (default: the scenario's duration)")
      ->check(finite_in(0.01, 3600.0));  // as a scenario's duration_s
  table.add(command, [options]() -> int { return run_sim(*options); });
}

}  // namespace dronetrack::apps
