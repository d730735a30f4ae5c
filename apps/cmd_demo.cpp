// `dronetrack demo`: the main job on an embedded default. Synthesises the bundled perimeter
// scene if it is missing, replays it at real time through the nodes and the fusion, and
// serves the operator page.
#include <filesystem>
#include <memory>

#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/data_paths.hpp"
#include "apps/replay_session.hpp"
#include "apps/signals.hpp"
#include "common/log.hpp"
#include "config/site_config.hpp"
#include "sim/render.hpp"
#include "sim/scenario.hpp"

namespace dronetrack::apps {
namespace {

struct Interrupted {};

struct DemoArguments {
  std::string scenario =
      data_path("scenarios/perimeter-two-drones.json", "config/scenarios/perimeter-two-drones.json")
          .string();
  std::string data_dir = "demo-data";
  std::string http = "127.0.0.1:8080";
  double duration_s = 0.0;
  bool fast = false;
};

// Synthesises the scene unless DIR/site.json is newer than the scenario file.
std::filesystem::path ensure_scene(const DemoArguments& arguments) {
  const std::filesystem::path scenario_file(arguments.scenario);
  const std::filesystem::path scene_dir(arguments.data_dir);
  const auto site_file = scene_dir / "site.json";
  std::error_code error;
  if (std::filesystem::exists(site_file, error) &&
      std::filesystem::last_write_time(site_file, error) >=
          std::filesystem::last_write_time(scenario_file, error)) {
    log::info("demo: using the scene already in ", scene_dir.string());
    return site_file;
  }
  log::info("demo: synthesising ", scenario_file.string(), " into ", scene_dir.string(),
            " (once; later runs reuse it)");
  std::vector<std::string> warnings;
  const sim::Scenario scenario = sim::load_scenario(scenario_file, warnings);
  for (const auto& warning : warnings) log::warn(warning);
  const sim::WrittenScene written = sim::write_scene(scenario, scene_dir, &install_stop_handlers());
  if (written.interrupted) throw Interrupted();
  return written.site;
}

int run(const DemoArguments& arguments) {
  std::filesystem::path site_file;
  try {
    site_file = ensure_scene(arguments);
  } catch (const Interrupted&) {
    log::error("demo: interrupted by ", stop_signal_name(), " while synthesising the scene");
    return interrupted_exit_code();
  }
  std::vector<std::string> warnings;
  const config::SiteConfig site = config::load_site_config(site_file, warnings);
  for (const auto& warning : warnings) log::warn(warning);
  ReplaySessionOptions options;
  options.http = arguments.http;
  options.realtime = !arguments.fast;
  options.max_duration_s = arguments.duration_s;
  options.tracks_out = (std::filesystem::path(arguments.data_dir) / "tracks.jsonl").string();
  options.doa_out = (std::filesystem::path(arguments.data_dir) / "doa.jsonl").string();
  options.keep_serving = arguments.duration_s <= 0.0;
  log::info("demo: open the URL below in a browser; tracks and DOAs are also written to ",
            arguments.data_dir, "/");
  return run_replay_session(site, options);
}

}  // namespace

void register_demo(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<DemoArguments>();
  auto* command = root.add_subcommand(
      "demo",
      "Synthesise the bundled perimeter scene (first run), replay it at real time "
      "through nodes and fusion, and serve the operator page");
  command->add_option("--scenario", arguments->scenario, "Scenario to synthesise")
      ->capture_default_str()
      ->check(CLI::ExistingFile);
  command
      ->add_option("--data-dir", arguments->data_dir,
                   "Where the synthesised scene and the outputs go")
      ->capture_default_str();
  command->add_option("--http", arguments->http, "Serve on ADDR:PORT")
      ->capture_default_str()
      ->check(http_address());
  command
      ->add_option("--duration-s", arguments->duration_s,
                   "Stop after this many seconds and exit (default: whole scene, then keep "
                   "serving until Ctrl-C)")
      ->check(finite_in(0.0, kMaxDuration_s));
  command->add_flag("--fast", arguments->fast, "Replay as fast as possible instead of real time");
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
