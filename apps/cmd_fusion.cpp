// `dronetrack fusion SITE.json [--tracks-out T.jsonl] [--http ADDR:PORT] [--domain N]`: the
// site's fusion as its own process. Subscribes Doa and NodeStatus, publishes Track and Alert,
// writes tracks as JSON lines (SPEC 3.2) and serves the web page's API. Ends cleanly on
// SIGINT/SIGTERM (pending output ticks are emitted, files flushed).
#include <chrono>
#include <memory>
#include <optional>

#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/dds_fusion_service.hpp"
#include "apps/dds_options.hpp"
#include "apps/dds_support.hpp"
#include "apps/jsonl_output.hpp"
#include "apps/live_state_observer.hpp"
#include "apps/metrics.hpp"
#include "apps/run_outputs.hpp"
#include "apps/signals.hpp"
#include "common/log.hpp"
#include "config/site_config.hpp"
#include "http_api/http_server.hpp"
#include "http_api/live_state.hpp"

namespace dronetrack::apps {
namespace {

struct FusionArguments {
  std::string site;
  std::string tracks_out;
  std::string http;
  std::string web_root;
  DdsOptions dds{{}, "fusion"};
  double duration_s = 0.0;
  std::string track_ids;
};

int run(const FusionArguments& arguments) {
  std::vector<std::string> warnings;
  config::LoadOptions load_options;
  load_options.check_recordings = false;  // the fusion never reads audio
  load_options.for_fusion = true;
  const config::SiteConfig site = config::load_site_config(arguments.site, warnings, load_options);
  for (const auto& warning : warnings) log::warn(warning);
  const int domain = resolve_domain(site, arguments.dds.domain);
  if (!arguments.tracks_out.empty())
    check_output_paths(site_inputs(site, false), {{"--tracks-out", arguments.tracks_out}});

  std::vector<std::unique_ptr<FusionObserver>> owned;
  TrackLinesWriter* track_writer = nullptr;
  if (!arguments.tracks_out.empty()) {
    // A service's output is a live log: appended (a restart never truncates what an earlier
    // run wrote), each tick flushed so a reader tailing it sees whole lines.
    auto writer =
        std::make_unique<TrackLinesWriter>(arguments.tracks_out, OutputFile::Mode::append);
    track_writer = writer.get();
    owned.push_back(std::move(writer));
  }
  std::unique_ptr<http_api::LiveState> live_state;
  FusionMetrics* metrics = nullptr;
  std::unique_ptr<http_api::HttpServer> server;
  if (!arguments.http.empty()) {
    live_state = std::make_unique<http_api::LiveState>(
        http_api::SiteLayout{site.geometries(), site.zones, site.speed_of_sound_mps});
    owned.push_back(std::make_unique<LiveStateObserver>(*live_state));
    auto fusion_metrics = std::make_unique<FusionMetrics>("fusion", array_ids(site));
    // Live nodes stamp Unix time: the latency is the wall clock minus a tick's time.
    fusion_metrics->set_stream_clock([] {
      return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
          .count();
    });
    metrics = fusion_metrics.get();
    owned.push_back(std::move(fusion_metrics));
    auto options =
        http_options_for(site, arguments.http, std::filesystem::path(arguments.web_root));
    options.metrics = [metrics] { return metrics->text(); };
    server = std::make_unique<http_api::HttpServer>(*live_state, std::move(options));
    server->start();
    log::info("fusion: serving ", server->url());
  }
  std::vector<FusionObserver*> observers;
  for (auto& observer : owned) observers.push_back(observer.get());

  const auto security = security_files(site, arguments.dds.identity);
  dds::Participant participant(domain, security ? &*security : nullptr);  // first: destroyed last
  FusionServiceOptions service_options;
  service_options.array_partitions = site.dds.secure();
  service_options.track_id_file = arguments.track_ids;
  DdsFusionService service(site, participant, observers, service_options);
  log::info("fusion: ", site.arrays.size(), " arrays, DDS domain ", domain);
  install_stop_handlers();
  const WallTimeLimit limit(arguments.duration_s);
  while (!stop_requested()) {
    service.poll(std::chrono::milliseconds(100));
    if (metrics) metrics->set_intake_counters(service.counters());
    if (limit.reached()) break;
  }
  service.finish();
  const IntakeCounters& counters = service.counters();
  const fusion::FusionCounters& engine = service.engine_counters();
  log::info("fusion: ", counters.doa_received, " DOAs received, ", counters.doa_accepted,
            " accepted, ", counters.doa_ignored(), " malformed, ", counters.doa_rejected_by_engine,
            " rejected by the engine (too late ", engine.rejected_too_late, ", duplicate ",
            engine.rejected_duplicate, "); ", engine.tracks_started, " tracks started; ",
            counters.tracks_published, " track samples and ", counters.alerts_published,
            " alerts published; nodes lost ", counters.nodes_lost, ", rejoined ",
            counters.nodes_rejoined, "; samples ahead of the site clock ", counters.clock_ahead,
            ", clock re-anchored ", counters.clock_reanchors);
  if (server) server->stop();
  if (track_writer) track_writer->output().commit();
  return stop_requested() ? interrupted_exit_code() : 0;
}

}  // namespace

void register_fusion(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<FusionArguments>();
  auto* command = root.add_subcommand(
      "fusion", "Run the site's fusion: DOAs in over DDS, tracks and zone alerts out");
  command->add_option("site", arguments->site, "Site config (JSON, SPEC 3.1)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--tracks-out", arguments->tracks_out,
                      "Write tracks as JSON lines here ('-' for stdout)");
  command->add_option("--http", arguments->http, "Serve the web page and JSON API on ADDR:PORT")
      ->check(http_address());
  command
      ->add_option(
          "--web-root", arguments->web_root,
          "With --http: folder of the web page (default: $DRONETRACK_WEB_ROOT or the built-in one)")
      ->check(CLI::ExistingDirectory);
  add_dds_options(*command, arguments->dds, "fusion");
  command->add_option("--track-ids", arguments->track_ids,
                      "State file of the track id high-water mark: a restarted fusion never "
                      "reuses an id an earlier one published (docs/contract.md)");
  add_duration_option(*command, arguments->duration_s);
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
