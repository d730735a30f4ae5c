#include "apps/dds_fusion_service.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "common/log.hpp"

namespace dronetrack::apps {

namespace {

using dds::SampleProblem;

// 2100-01-01 in Unix nanoseconds: later is no clock, it is garbage.
constexpr std::int64_t kLatestPlausibleNs = 4'102'444'800LL * 1'000'000'000LL;
// Times below this are recording times (t = 0 at sample 0); above, Unix times (live nodes).
constexpr std::int64_t kUnixTimeThresholdNs = 1'000'000LL * 1'000'000'000LL;  // 11.6 days

// Warning kinds for ThrottledWarnings: Doa problems, then NodeStatus problems, then the engine.
constexpr int kStatusKindOffset = dds::kSampleProblemCount;
constexpr int kEngineKind = 2 * dds::kSampleProblemCount;

const char* doa_problem_text(SampleProblem problem) {
  switch (problem) {
    case SampleProblem::empty_key:
      return "Doa with an empty array id";
    case SampleProblem::unknown_array:
      return "Doa from an array not in the site config";
    case SampleProblem::non_finite:
      return "Doa with NaN/Inf values";
    case SampleProblem::absurd_time:
      return "Doa with an absurd time (negative, past 2100, or ahead of the site clock: a node "
             "whose clock jumped?)";
    case SampleProblem::oversized_sequence:
      return "Doa with an oversized TDOA sequence";
    case SampleProblem::bad_value:
      return "Doa with an invalid value (direction, covariance, enum)";
    case SampleProblem::foreign_partition:
      return "Doa naming an array other than its writer's partition (a node speaking for "
             "another array)";
    case SampleProblem::none:
      break;
  }
  return "Doa";
}

const char* status_problem_text(SampleProblem problem) {
  switch (problem) {
    case SampleProblem::empty_key:
      return "NodeStatus with an empty array id";
    case SampleProblem::unknown_array:
      return "NodeStatus from an array not in the site config";
    case SampleProblem::non_finite:
      return "NodeStatus with NaN/Inf values";
    case SampleProblem::absurd_time:
      return "NodeStatus with an absurd time (negative, past 2100, or ahead of the site clock)";
    case SampleProblem::oversized_sequence:
    case SampleProblem::bad_value:
      return "NodeStatus with an invalid value";
    case SampleProblem::foreign_partition:
      return "NodeStatus naming an array other than its writer's partition";
    case SampleProblem::none:
      break;
  }
  return "NodeStatus";
}

}  // namespace

std::int64_t IntakeCounters::doa_ignored() const {
  std::int64_t total = 0;
  for (std::int64_t count : doa_problems) total += count;
  return total;
}

// Sits between the FusionDriver and the outputs: adds the time base back and writes Track and
// Alert samples. Track ids that disappear between ticks are disposed, so late joiners never see
// a track that has ended, and then unregistered: track ids are never reused, and a registered
// instance stays in this writer (its transient-local history keeps the last sample of each) and
// in every reader until it is unregistered, so each ended track would otherwise be kept for the
// life of the process (issue 18, the soak).
class DdsFusionService::Outputs : public FusionObserver {
 public:
  Outputs(const std::int64_t& base_ns, TrackIdReservation& track_ids,
          const dds::Writer<dronetrack_Track>& track_writer,
          const dds::Writer<dronetrack_Alert>& alert_writer, std::vector<FusionObserver*> observers,
          IntakeCounters& counters)
      : base_ns_(base_ns),
        track_ids_(track_ids),
        track_writer_(track_writer),
        alert_writer_(alert_writer),
        observers_(std::move(observers)),
        counters_(counters) {
    tracks_.reserve(64);
    previous_ids_.reserve(64);
    current_ids_.reserve(64);
  }

  void on_doa(const doa::DoaMeasurement& measurement) override {
    doa_ = measurement;
    doa_.time_s += base_s();
    for (auto* observer : observers_) observer->on_doa(doa_);
  }
  void on_node_status(const doa::NodeStatus& status) override {
    for (auto* observer : observers_) observer->on_node_status(status);  // already wire time
  }
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) override {
    const double shift_s = base_s();
    tracks_.assign(tracks.begin(), tracks.end());
    current_ids_.clear();
    for (auto& track : tracks_) {
      track.time_s += shift_s;
      track.last_update_s += shift_s;
      track.id = track_ids_.wire_id(track.id);
      current_ids_.push_back(track.id);
      dds::to_idl(track, track_sample_);
      if (track_writer_.try_write(track_sample_) >= 0) ++counters_.tracks_published;
    }
    for (int id : previous_ids_) {
      if (std::find(current_ids_.begin(), current_ids_.end(), id) != current_ids_.end()) continue;
      dronetrack_Track key{};
      key.id = id;
      dds_dispose(track_writer_.handle(), &key);
      dds_unregister_instance(track_writer_.handle(), &key);
    }
    std::swap(previous_ids_, current_ids_);
    for (auto* observer : observers_) observer->on_tracks(time_s + shift_s, tracks_);
  }
  void on_zone_event(const fusion::ZoneEvent& event) override {
    event_ = event;
    event_.time_s += base_s();
    event_.track_id = track_ids_.wire_id(event_.track_id);
    dds::to_idl(event_, alert_sample_);
    if (alert_writer_.try_write(alert_sample_) >= 0) ++counters_.alerts_published;
    // An alert is an event, not a state: its (zone, track) instance is unregistered at once so
    // it lives only as long as its samples (delivered reliably all the same; readers take them
    // as usual). Kept registered, every track that ever alerted would stay in this writer and in
    // every Alert reader.
    dds_unregister_instance(alert_writer_.handle(), &alert_sample_);
    log::info("alert: track ", event_.track_id, event_.entered ? " entered " : " left ",
              event_.zone, " at t=", event_.time_s);
    for (auto* observer : observers_) observer->on_zone_event(event_);
  }
  void on_counters(const fusion::FusionCounters& counters) override {
    for (auto* observer : observers_) observer->on_counters(counters);
  }
  void on_time(double time_s) override {
    for (auto* observer : observers_) observer->on_time(time_s + base_s());
  }

 private:
  double base_s() const { return static_cast<double>(base_ns_ / 1'000'000'000); }

  const std::int64_t& base_ns_;
  TrackIdReservation& track_ids_;
  const dds::Writer<dronetrack_Track>& track_writer_;
  const dds::Writer<dronetrack_Alert>& alert_writer_;
  std::vector<FusionObserver*> observers_;
  IntakeCounters& counters_;
  std::vector<fusion::TrackReport> tracks_;
  std::vector<int> previous_ids_;
  std::vector<int> current_ids_;
  doa::DoaMeasurement doa_;
  fusion::ZoneEvent event_;
  dronetrack_Track track_sample_{};
  dronetrack_Alert alert_sample_{};
};

namespace {
template <class Fill>
dds::Qos make_qos(Fill fill, bool array_partitions) {
  dds::Qos qos;
  fill(qos);
  if (array_partitions) qos.partitions({dds::array_partition("*")});
  return qos;
}
}  // namespace

DdsFusionService::DdsFusionService(const config::SiteConfig& site,
                                   const dds::Participant& participant,
                                   std::vector<FusionObserver*> observers,
                                   FusionServiceOptions options)
    : array_ids_(array_ids(site)),
      options_(options),
      doa_topic_(participant),
      status_topic_(participant),
      track_topic_(participant),
      alert_topic_(participant),
      doa_reader_(participant, doa_topic_, make_qos(dds::doa_reader_qos, options.array_partitions)),
      status_reader_(participant, status_topic_,
                     make_qos(dds::status_reader_qos, options.array_partitions),
                     DDS_LIVELINESS_CHANGED_STATUS),
      track_writer_(participant, track_topic_, make_qos(dds::track_writer_qos, false)),
      alert_writer_(participant, alert_topic_, make_qos(dds::alert_writer_qos, false)),
      waitset_(participant),
      track_ids_(options.track_id_file),
      outputs_(std::make_unique<Outputs>(base_ns_, track_ids_, track_writer_, alert_writer_,
                                         std::move(observers), counters_)),
      driver_(site, {outputs_.get()}) {
  waitset_.attach(doa_reader_.read_condition());
  waitset_.attach(status_reader_.read_condition());
  // The reader itself: wakes on LIVELINESS_CHANGED (enabled above, read in take_statuses).
  waitset_.attach(status_reader_.handle());
  for (const auto& id : array_ids_) nodes_[id] = NodeState{};
}

DdsFusionService::~DdsFusionService() { warnings_.flush(); }

void DdsFusionService::poll(std::chrono::nanoseconds timeout) {
  waitset_.wait(timeout);
  const std::int64_t newest_before = newest_ns_;
  take_statuses();
  take_doas();
  check_silent_nodes();
  if (have_time_ && newest_ns_ > newest_before) driver_.advance_to(rebased(newest_ns_));
}

void DdsFusionService::finish() {
  driver_.finish();
  warnings_.flush();
}

bool DdsFusionService::node_alive(const std::string& array_id) const {
  const auto found = nodes_.find(array_id);
  return found != nodes_.end() && found->second.alive;
}

double DdsFusionService::latest_time_s() const {
  return have_time_ ? dds::ns_to_seconds(newest_ns_) : std::numeric_limits<double>::quiet_NaN();
}

double DdsFusionService::rebased(std::int64_t time_ns) const {
  return dds::ns_to_seconds(time_ns - base_ns_);
}

bool DdsFusionService::plausible_time(std::int64_t time_ns, SampleProblem& problem) {
  if (time_ns < 0 || time_ns > kLatestPlausibleNs) {
    problem = SampleProblem::absurd_time;
    return false;
  }
  const auto now = std::chrono::steady_clock::now();
  if (have_time_) {
    const std::int64_t clock_ns =
        newest_ns_ + std::chrono::duration_cast<std::chrono::nanoseconds>(now - newest_at_).count();
    const double lead_s = dds::ns_to_seconds(time_ns - clock_ns);
    if (lead_s > options_.max_clock_lead_s) {
      if (now - consistent_at_ < options_.clock_reanchor_after) {
        problem = SampleProblem::absurd_time;
        ++counters_.clock_ahead;
        return false;
      }
      ++counters_.clock_reanchors;
      log::warn("fusion: no sample on the site clock for ",
                std::chrono::duration<double>(now - consistent_at_).count(),
                " s; the clock follows the nodes heard now, ", lead_s, " s ahead");
    }
  }
  consistent_at_ = now;
  if (time_ns > newest_ns_ || !have_time_) newest_at_ = now;
  if (!have_time_) {
    have_time_ = true;
    // Live times are rebased to a whole second so the driver's tick counter starts near 0;
    // recording times stay as they are (t = 0 is sample 0 of every recording).
    base_ns_ = time_ns >= kUnixTimeThresholdNs ? time_ns / 1'000'000'000 * 1'000'000'000 : 0;
    newest_ns_ = time_ns;
  }
  newest_ns_ = std::max(newest_ns_, time_ns);
  return true;
}

void DdsFusionService::take_doas() {
  for (;;) {
    dds::Samples<dronetrack_Doa> samples = doa_reader_.take();
    if (samples.empty()) return;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (!samples.info(i).valid_data) continue;  // instance changes: followed via NodeStatus
      ++counters_.doa_received;
      SampleProblem problem = dds::from_idl(samples.data(i), array_ids_, measurement_);
      if (problem == SampleProblem::none &&
          !from_own_partition(doa_reader_.handle(), samples.info(i), measurement_.array_id)) {
        problem = SampleProblem::foreign_partition;
      }
      if (problem == SampleProblem::none) plausible_time(samples.data(i).time_ns, problem);
      if (problem != SampleProblem::none) {
        ++counters_.doa_problems[static_cast<int>(problem)];
        warnings_.count(static_cast<int>(problem), doa_problem_text(problem));
        continue;
      }
      measurement_.time_s = rebased(samples.data(i).time_ns);
      const fusion::DoaVerdict verdict = driver_.on_doa(measurement_);
      if (verdict == fusion::DoaVerdict::accepted) {
        ++counters_.doa_accepted;
      } else {
        ++counters_.doa_rejected_by_engine;
        warnings_.count(kEngineKind, "Doa rejected by the fusion engine (late, duplicate, bad)");
      }
    }
  }
}

bool DdsFusionService::from_own_partition(dds_entity_t reader, const dds_sample_info_t& info,
                                          const std::string& array_id) {
  if (!options_.array_partitions) return true;
  auto found = writer_partitions_.find(info.publication_handle);
  if (found == writer_partitions_.end()) {
    std::vector<std::string> names;
    if (dds_builtintopic_endpoint_t* writer =
            dds_get_matched_publication_data(reader, info.publication_handle)) {
      uint32_t count = 0;
      char** partitions = nullptr;
      if (writer->qos != nullptr && dds_qget_partition(writer->qos, &count, &partitions)) {
        for (uint32_t k = 0; k < count; ++k) {
          names.emplace_back(partitions[k]);
          dds_free(partitions[k]);
        }
        dds_free(partitions);
      }
      dds_builtintopic_free_endpoint(writer);
    }
    found = writer_partitions_.emplace(info.publication_handle, std::move(names)).first;
  }
  const std::string own = dds::array_partition(array_id);
  for (const std::string& name : found->second) {
    if (name == own) return true;
  }
  return false;
}

void DdsFusionService::take_statuses() {
  const dds_liveliness_changed_status_t liveliness = status_reader_.liveliness();
  if (liveliness.not_alive_count_change > 0) {
    log::info("fusion: ", liveliness.not_alive_count_change,
              " NodeStatus writer(s) lost liveliness (", liveliness.alive_count, " alive)");
  }
  for (;;) {
    dds::Samples<dronetrack_NodeStatus> samples = status_reader_.take();
    if (samples.empty()) return;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const dronetrack_NodeStatus& sample = samples.data(i);
      const dds_sample_info_t& info = samples.info(i);
      if (!info.valid_data) {
        // Only the key is meaningful: the node's writer is gone (liveliness lost, or it ended).
        if (info.instance_state != DDS_ALIVE_INSTANCE_STATE) {
          const std::string_view id(sample.array_id, strnlen(sample.array_id, 65));
          mark_stale(std::string(id), info.instance_state == DDS_NOT_ALIVE_NO_WRITERS_INSTANCE_STATE
                                          ? "liveliness lost"
                                          : "disposed");
        }
        continue;
      }
      ++counters_.status_received;
      SampleProblem problem = dds::from_idl(sample, array_ids_, status_);
      if (problem == SampleProblem::none &&
          !from_own_partition(status_reader_.handle(), info, status_.array_id)) {
        problem = SampleProblem::foreign_partition;
      }
      if (problem == SampleProblem::none) plausible_time(sample.time_ns, problem);
      if (problem != SampleProblem::none) {
        ++counters_.status_problems[static_cast<int>(problem)];
        warnings_.count(kStatusKindOffset + static_cast<int>(problem),
                        status_problem_text(problem));
        continue;
      }
      NodeState& node = nodes_[status_.array_id];
      node.last_report = std::chrono::steady_clock::now();
      if (status_.alive && !node.alive) {
        log::info("fusion: array ", status_.array_id, " alive (", status_.software_version, ", ",
                  status_.sample_rate_hz, " Hz)");
        if (node.last.sample_rate_hz > 0.0) ++counters_.nodes_rejoined;
      } else if (!status_.alive && node.alive) {
        log::info("fusion: array ", status_.array_id, " stopped");
      }
      node.alive = status_.alive;
      node.last = status_;
      driver_.on_node_status(status_);
    }
  }
}

void DdsFusionService::check_silent_nodes() {
  const auto now = std::chrono::steady_clock::now();
  for (auto& [id, node] : nodes_) {
    if (node.alive && now - node.last_report > options_.status_silence_limit) {
      mark_stale(id, "no status report within the silence limit");
    }
  }
}

void DdsFusionService::mark_stale(const std::string& array_id, const char* why) {
  const auto found = nodes_.find(array_id);
  if (found == nodes_.end() || !found->second.alive) return;
  NodeState& node = found->second;
  node.alive = false;
  ++counters_.nodes_lost;
  log::warn("fusion: array ", array_id, " stale: ", why);
  doa::NodeStatus status = node.last;
  status.alive = false;
  driver_.on_node_status(status);
}

}  // namespace dronetrack::apps
