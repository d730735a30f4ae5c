#include "apps/metrics.hpp"

#include <cmath>
#include <utility>

#include "apps/dds_fusion_service.hpp"
#include "dds_idl/conversions.hpp"
#include "fusion/track_classifier.hpp"
#include "fusion/zone_monitor.hpp"

namespace dronetrack::apps {
namespace {

using Type = http_api::MetricsText::Type;

static_assert(dds::kSampleProblemCount == 8, "FusionMetrics::kProblems follows SampleProblem");

// A stream further from the wall clock than this is not on it (recordings over DDS: times since
// the recording's start) and gives no latency.
constexpr double kMaxLatency_s = 3600.0;

void build_info(http_api::MetricsText& out, const std::string& role) {
  out.family("dronetrack_build_info", Type::gauge,
             "Always 1; the labels say which build and which role serves these metrics");
  out.sample("dronetrack_build_info", 1.0, {{"version", DRONETRACK_VERSION}, {"role", role}});
}

using Counts = std::pair<const char*, std::int64_t>;

// One counter family, a sample per (value of `label`, count), each also labelled with the
// array when one is given.
template <std::size_t N>
void labelled_counters(http_api::MetricsText& out, const char* name, const char* help,
                       const char* label, const Counts (&counts)[N],
                       const std::string* array = nullptr) {
  out.family(name, Type::counter, help);
  for (const auto& [value, count] : counts) {
    if (array != nullptr) {
      out.sample(name, static_cast<double>(count), {{"array", *array}, {label, value}});
    } else {
      out.sample(name, static_cast<double>(count), {{label, value}});
    }
  }
}

}  // namespace

FusionMetrics::FusionMetrics(std::string role, std::vector<std::string> array_ids)
    : role_(std::move(role)),
      array_ids_(std::move(array_ids)),
      nodes_(array_ids_.size()),
      // From a few frames to seconds behind; the reorder window alone is 0.3 s by default.
      latency_s_({0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0}) {}

void FusionMetrics::set_stream_clock(std::function<double()> wall_stream_s) {
  std::lock_guard lock(mutex_);
  wall_stream_s_ = std::move(wall_stream_s);
}

void FusionMetrics::set_intake_counters(const IntakeCounters& counters) {
  std::lock_guard lock(mutex_);
  have_intake_ = true;
  doa_received_ = counters.doa_received;
  for (std::size_t p = 0; p < kProblems; ++p) {
    doa_problems_[p] = counters.doa_problems[p];
    status_problems_[p] = counters.status_problems[p];
  }
}

void FusionMetrics::on_counters(const fusion::FusionCounters& counters) {
  std::lock_guard lock(mutex_);
  engine_ = counters;
}

void FusionMetrics::on_node_status(const doa::NodeStatus& status) {
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < array_ids_.size(); ++i) {
    if (array_ids_[i] != status.array_id) continue;
    // Counts since the node started: the newest report holds them all.
    nodes_[i] = {status.overruns, status.clipped_samples, status.non_finite_samples, true};
    return;
  }
}

void FusionMetrics::on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) {
  std::lock_guard lock(mutex_);
  for (auto& by_class : tracks_) by_class.fill(0);
  for (const auto& track : tracks) {
    const auto status = static_cast<std::size_t>(track.status);
    const auto track_class = static_cast<std::size_t>(track.track_class);
    if (status < kStatuses && track_class < kClasses) ++tracks_[status][track_class];
  }
  ++ticks_;
  if (wall_stream_s_) {
    const double latency_s = wall_stream_s_() - time_s;
    if (latency_s >= 0.0 && latency_s < kMaxLatency_s) latency_s_.observe(latency_s);
  }
}

void FusionMetrics::on_zone_event(const fusion::ZoneEvent& event) {
  std::lock_guard lock(mutex_);
  const auto kind = static_cast<std::size_t>(fusion::kind_of(event));
  if (kind < kEvents) ++alerts_[kind];
}

std::string FusionMetrics::text() const {
  std::lock_guard lock(mutex_);
  http_api::MetricsText out;
  build_info(out, role_);

  const Counts verdicts[] = {{"accepted", engine_.accepted},
                             {"non_finite", engine_.rejected_non_finite},
                             {"unknown_array", engine_.rejected_unknown_array},
                             {"too_late", engine_.rejected_too_late},
                             {"duplicate", engine_.rejected_duplicate},
                             {"bad_direction", engine_.rejected_bad_direction}};
  labelled_counters(out, "dronetrack_fusion_doas_total",
                    "DOAs that reached the fusion engine, by its verdict", "verdict", verdicts);
  out.family("dronetrack_fusion_doas_gated_out_total", Type::counter,
             "Accepted DOAs that matched no track and started none");
  out.sample("dronetrack_fusion_doas_gated_out_total", static_cast<double>(engine_.gated_out));
  const Counts candidates[] = {{"ghost", engine_.ghosts_rejected},
                               {"below_ground", engine_.below_ground_rejected}};
  labelled_counters(out, "dronetrack_fusion_candidates_rejected_total",
                    "Triangulated candidate points refused, by reason", "reason", candidates);
  const Counts track_events[] = {{"started", engine_.tracks_started},
                                 {"confirmed", engine_.tracks_confirmed},
                                 {"deleted", engine_.tracks_deleted},
                                 {"duplicate_pruned", engine_.duplicates_pruned}};
  labelled_counters(out, "dronetrack_fusion_track_events_total",
                    "Tracks started, confirmed and deleted (duplicate_pruned: of the deleted, "
                    "duplicates along a sharper track's ray)",
                    "event", track_events);
  out.family("dronetrack_fusion_ticks_total", Type::counter, "Track output ticks emitted");
  out.sample("dronetrack_fusion_ticks_total", static_cast<double>(ticks_));

  out.family("dronetrack_tracks", Type::gauge,
             "Live tracks at the last output tick, by status and class (as /api/tracks)");
  for (std::size_t s = 0; s < kStatuses; ++s) {
    for (std::size_t c = 0; c < kClasses; ++c) {
      out.sample("dronetrack_tracks", static_cast<double>(tracks_[s][c]),
                 {{"status", fusion::to_string(static_cast<fusion::TrackStatus>(s))},
                  {"class", fusion::to_string(static_cast<fusion::TrackClass>(c))}});
    }
  }
  out.family("dronetrack_alerts_total", Type::counter,
             "Zone alerts and class changes (the alert lines), by event");
  for (std::size_t e = 0; e < kEvents; ++e) {
    out.sample("dronetrack_alerts_total", static_cast<double>(alerts_[e]),
               {{"event", fusion::to_string(static_cast<fusion::ZoneEventKind>(e))}});
  }
  out.family("dronetrack_track_latency_seconds", Type::histogram,
             "Wall time from a track tick's stream time (the audio it describes) to its output; "
             "observed only where the stream runs on the wall clock (live nodes, replay "
             "--realtime)");
  out.histogram("dronetrack_track_latency_seconds", latency_s_);

  // Each array's counts from its last NodeStatus (those not yet heard from are left out).
  struct NodeFamily {
    const char* name;
    const char* help;
    std::int64_t NodeCounts::*count;
  };
  const NodeFamily node_families[] = {
      {"dronetrack_node_overruns_total",
       "Audio blocks a node lost because it was late, from its last NodeStatus",
       &NodeCounts::overruns},
      {"dronetrack_node_clipped_samples_total",
       "Samples at or beyond 0.999 of full scale, all channels, from the last NodeStatus",
       &NodeCounts::clipped_samples},
      {"dronetrack_node_non_finite_samples_total",
       "NaN or infinite samples, all channels, from the last NodeStatus",
       &NodeCounts::non_finite_samples}};
  for (const NodeFamily& family : node_families) {
    out.family(family.name, Type::counter, family.help);
    for (std::size_t i = 0; i < array_ids_.size(); ++i) {
      if (nodes_[i].reported)
        out.sample(family.name, static_cast<double>(nodes_[i].*family.count),
                   {{"array", array_ids_[i]}});
    }
  }

  if (have_intake_) {
    out.family("dronetrack_dds_doa_samples_received_total", Type::counter,
               "Doa samples taken from DDS");
    out.sample("dronetrack_dds_doa_samples_received_total", static_cast<double>(doa_received_));
    out.family("dronetrack_dds_samples_rejected_total", Type::counter,
               "DDS samples ignored before the engine, by topic and problem");
    for (std::size_t p = 1; p < kProblems; ++p) {  // 0 is "none"
      const char* problem = dds::to_string(static_cast<dds::SampleProblem>(p));
      out.sample("dronetrack_dds_samples_rejected_total", static_cast<double>(doa_problems_[p]),
                 {{"topic", "Doa"}, {"problem", problem}});
      out.sample("dronetrack_dds_samples_rejected_total", static_cast<double>(status_problems_[p]),
                 {{"topic", "NodeStatus"}, {"problem", problem}});
    }
  }
  return out.text();
}

NodeMetrics::NodeMetrics(std::string array_id) : array_id_(std::move(array_id)) {}

void NodeMetrics::update(std::int64_t doas_published, std::int64_t write_failures,
                         const doa::NodeDiagnostics& diagnostics, std::int64_t overruns) {
  std::lock_guard lock(mutex_);
  doas_published_ = doas_published;
  write_failures_ = write_failures;
  diagnostics_ = diagnostics;
  overruns_ = overruns;
}

std::string NodeMetrics::text() const {
  std::lock_guard lock(mutex_);
  http_api::MetricsText out;
  build_info(out, "node");
  const http_api::MetricLabels array = {{"array", array_id_}};
  out.family("dronetrack_node_frames_total", Type::counter, "Analysis frames processed");
  out.sample("dronetrack_node_frames_total", static_cast<double>(diagnostics_.frames_processed),
             array);
  out.family("dronetrack_node_doas_published_total", Type::counter, "Doa samples written to DDS");
  out.sample("dronetrack_node_doas_published_total", static_cast<double>(doas_published_), array);
  out.family("dronetrack_node_doa_write_failures_total", Type::counter,
             "DDS writes (Doa, NodeStatus) that failed");
  out.sample("dronetrack_node_doa_write_failures_total", static_cast<double>(write_failures_),
             array);
  const Counts rejects[] = {{"below_horizon", diagnostics_.below_horizon_rejected},
                            {"unposed", diagnostics_.unposed_doas},
                            {"bad_block", diagnostics_.rejected_blocks},
                            {"stream_gap", diagnostics_.stream_gaps}};
  labelled_counters(out, "dronetrack_node_rejects_total",
                    "What the node's pipeline refused or dropped, by reason", "reason", rejects,
                    &array_id_);
  out.family("dronetrack_node_overruns_total", Type::counter,
             "Audio blocks lost because the node was late");
  out.sample("dronetrack_node_overruns_total", static_cast<double>(overruns_), array);
  out.family("dronetrack_node_clipped_samples_total", Type::counter,
             "Samples at or beyond 0.999 of full scale, all channels");
  out.sample("dronetrack_node_clipped_samples_total",
             static_cast<double>(diagnostics_.clipped_samples), array);
  out.family("dronetrack_node_non_finite_samples_total", Type::counter,
             "NaN or infinite samples, all channels");
  out.sample("dronetrack_node_non_finite_samples_total",
             static_cast<double>(diagnostics_.non_finite_samples), array);
  out.family("dronetrack_node_snr_db", Type::gauge, "In-band SNR of the last frame, dB");
  out.sample("dronetrack_node_snr_db", diagnostics_.snr_db, array);
  return out.text();
}

}  // namespace dronetrack::apps
