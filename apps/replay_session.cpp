#include "apps/replay_session.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "apps/array_node.hpp"
#include "apps/dds_support.hpp"
#include "apps/doa_file_replay.hpp"
#include "apps/incident_recorder.hpp"
#include "apps/jsonl_output.hpp"
#include "apps/live_state_observer.hpp"
#include "apps/metrics.hpp"
#include "apps/plot_recorder.hpp"
#include "apps/recording_alignment.hpp"
#include "apps/replay_runner.hpp"
#include "apps/run_outputs.hpp"
#include "apps/signals.hpp"
#include "capture/recording_info.hpp"
#include "common/log.hpp"
#include "http_api/http_server.hpp"

namespace dronetrack::apps {
namespace {

void log_fusion_counters(const fusion::FusionCounters& counters) {
  log::info("fusion: ", counters.accepted,
            " DOAs accepted; rejected: ", counters.rejected_non_finite, " non-finite, ",
            counters.rejected_unknown_array, " unknown array, ", counters.rejected_too_late,
            " too late, ", counters.rejected_duplicate, " duplicate, ",
            counters.rejected_bad_direction, " bad direction; ", counters.gated_out,
            " matched no track; tracks started ", counters.tracks_started, ", confirmed ",
            counters.tracks_confirmed, ", deleted ", counters.tracks_deleted);
}

}  // namespace

int run_replay_session(const config::SiteConfig& site, const ReplaySessionOptions& options) {
  // Everything that can refuse the run does so before any output exists: the paths, the DOA
  // lines, the HTTP address. The outputs themselves only replace their targets at the end.
  const bool tracks_to_stdout =
      options.tracks_out.empty() && options.doa_out.empty() && options.http.empty();
  const std::string tracks_out = tracks_to_stdout ? std::string("-") : options.tracks_out;
  {
    std::vector<NamedPath> inputs = site_inputs(site, options.doa_in.empty());
    if (!options.doa_in.empty()) inputs.push_back({"--doa-in", options.doa_in});
    std::vector<NamedPath> outputs;
    if (!tracks_out.empty()) outputs.push_back({"--tracks-out", tracks_out});
    if (!options.doa_out.empty()) outputs.push_back({"--doa-out", options.doa_out});
    if (!options.tdoa_out.empty()) outputs.push_back({"--tdoa-out", options.tdoa_out});
    if (!options.alerts_out.empty()) outputs.push_back({"--alerts-out", options.alerts_out});
    if (!options.plot_out.empty()) outputs.push_back({"--plot", options.plot_out});
    check_output_paths(inputs, outputs);
  }
  if (options.doa_in.empty()) {
    // A moving array's recording must lie within its pose file's span.
    for (std::size_t i = 0; i < site.arrays.size(); ++i) {
      const std::string problem =
          pose_span_problem(site, i, site.arrays[i].recording, options.max_duration_s);
      if (!problem.empty()) throw std::runtime_error(problem);
      if (site.arrays[i].pose_topic && site.arrays[i].pose_file.empty())
        log::warn("array ", site.arrays[i].geometry.id,
                  " moves (pose_topic) but has no pose_file: replay takes its config pose as "
                  "fixed");
    }
  }
  RecordingAlignment alignment;
  if (options.doa_in.empty()) alignment = align_recordings(site);
  std::vector<doa::DoaMeasurement> recorded_doas;
  if (!options.doa_in.empty()) {
    recorded_doas = read_doa_measurements(options.doa_in, site);
    const std::string problem = audio_end_problem(recorded_doas, options.doa_in_audio_end_s);
    if (!problem.empty()) throw std::runtime_error(problem);
  }
  if (options.doa_outliers.share > 0.0) {
    const sim::AlphaStable& law = options.doa_outliers.law_deg;
    const std::size_t perturbed = sim::add_doa_outliers(recorded_doas, options.doa_outliers);
    log::info("replay: ", perturbed, " of ", recorded_doas.size(), " DOAs made outliers (share ",
              options.doa_outliers.share, ", alpha-stable alpha ", law.alpha, ", scale ", law.scale,
              " deg, seed ", options.doa_outliers.seed, ")");
  }

  // Serving: the live state is fed like any other output; the server reads snapshots of it.
  std::unique_ptr<http_api::LiveState> live_state;
  std::unique_ptr<LiveStateObserver> live_observer;
  std::unique_ptr<FusionMetrics> metrics;
  std::unique_ptr<http_api::HttpServer> server;
  if (!options.http.empty()) {
    live_state = std::make_unique<http_api::LiveState>(
        http_api::SiteLayout{site.geometries(), site.zones, site.speed_of_sound_mps});
    live_observer = std::make_unique<LiveStateObserver>(*live_state);
    metrics = std::make_unique<FusionMetrics>("replay", array_ids(site));
    auto http_options = http_options_for(site, options.http);
    http_options.metrics = [&metrics] { return metrics->text(); };
    server = std::make_unique<http_api::HttpServer>(*live_state, std::move(http_options));
    server->start();
  }

  if (stop_requested()) {  // while reading: nothing was produced, so nothing is kept
    log::error("replay: interrupted by ", stop_signal_name(), " before any output was written");
    return interrupted_exit_code();
  }

  std::unique_ptr<DoaLinesWriter> doa_writer;
  std::unique_ptr<TdoaLinesWriter> tdoa_writer;
  std::unique_ptr<AlertLinesWriter> alert_writer;
  std::unique_ptr<TrackLinesWriter> track_writer;
  RunOutputs outputs;
  std::vector<FusionObserver*> observers;
  if (!options.doa_out.empty()) {
    doa_writer = std::make_unique<DoaLinesWriter>(options.doa_out);
    outputs.add(doa_writer->output());
    observers.push_back(doa_writer.get());
  }
  if (!options.tdoa_out.empty()) {
    tdoa_writer = std::make_unique<TdoaLinesWriter>(options.tdoa_out);
    outputs.add(tdoa_writer->output());
    observers.push_back(tdoa_writer.get());
  }
  if (!options.alerts_out.empty()) {
    alert_writer = std::make_unique<AlertLinesWriter>(options.alerts_out);
    outputs.add(alert_writer->output());
    observers.push_back(alert_writer.get());
  }
  std::unique_ptr<PlotRecorder> plot;
  if (!options.plot_out.empty()) {
    plot = std::make_unique<PlotRecorder>(options.plot_out, "dronetrack replay");
    outputs.add(plot->output());
    observers.push_back(plot.get());
  }
  if (!tracks_out.empty()) {
    track_writer = std::make_unique<TrackLinesWriter>(tracks_out);
    outputs.add(track_writer->output());
    observers.push_back(track_writer.get());
  }
  if (live_observer) observers.push_back(live_observer.get());
  if (metrics) observers.push_back(metrics.get());
  std::unique_ptr<IncidentRecorder> incidents;
  if (site.incident.enabled() && options.doa_in.empty()) {
    std::vector<IncidentArray> arrays;
    for (std::size_t i = 0; i < site.arrays.size(); ++i)
      arrays.push_back({static_cast<int>(i),
                        capture::probe_recording(site.arrays[i].recording).sample_rate_hz,
                        static_cast<int>(site.arrays[i].geometry.mic_count())});
    incidents = std::make_unique<IncidentRecorder>(
        site, std::move(arrays),
        IncidentClock{alignment.utc_start_unix_ns, alignment.from_recordings ? "system" : "replay",
                      true});
    observers.push_back(incidents.get());
  }
  if (server) {
    // The URL goes to stdout too: it is what a person running the demo looks for.
    std::printf("dronetrack: serving %s\n", server->url().c_str());
    std::fflush(stdout);
  }

  ReplaySummary summary;
  if (!options.doa_in.empty()) {
    summary = replay_doas(site, recorded_doas, observers, &install_stop_handlers(),
                          options.doa_in_audio_end_s);
    log::info("replay: ", summary.doas, " DOAs of ", options.doa_in, " (", summary.stream_s,
              " s) through the fusion in ", summary.wall_s, " s (", summary.doas_accepted,
              " accepted), ", summary.ticks, " track ticks");
  } else {
    ReplayOptions replay_options;
    replay_options.realtime = options.realtime;
    replay_options.max_duration_s = options.max_duration_s;
    if (metrics && options.realtime) {
      // Paced: stream time t is due t seconds after the start, so the latency has a wall clock.
      replay_options.on_start = [&metrics] {
        const auto start = std::chrono::steady_clock::now();
        metrics->set_stream_clock([start] {
          return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        });
      };
    }
    replay_options.start_samples = alignment.start_samples;
    replay_options.incidents = incidents.get();
    summary = run_replay(site, observers, replay_options, &install_stop_handlers());
    log::info("replay: ", summary.stream_s, " s of audio in ", summary.wall_s, " s (",
              summary.stream_s / std::max(summary.wall_s, 1e-9), "x real time), ", summary.doas,
              " DOAs (", summary.doas_accepted, " accepted), ", summary.ticks, " track ticks");
  }
  log_fusion_counters(summary.counters);
  if (plot) plot->write();
  if (incidents) {
    std::int64_t errors = 0;
    for (const doa::NodeStatus& node : summary.nodes) errors += node.incident_write_errors;
    log::info("incident: ", incidents->clips_saved(), " clip(s) saved in ",
              site.incident.directory.string(), ", ", errors, " write error(s)");
  }
  const int exit_code = outputs.finish("replay", summary.cut_short);
  if (exit_code != 0) return exit_code;
  if (server && options.keep_serving && !stop_requested()) {
    log::info("recordings finished; still serving ", server->url(), " (Ctrl-C to stop)");
    wait_for_stop();
    return interrupted_exit_code();  // the outputs were complete and are in place
  }
  return 0;
}

}  // namespace dronetrack::apps
