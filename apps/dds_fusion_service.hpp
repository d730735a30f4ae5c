#pragma once
// The fusion process's DDS side: takes Doa and NodeStatus samples, validates every one (a remote
// process can send anything), feeds the valid ones to a FusionDriver, publishes Track and Alert
// samples per output tick, and follows node liveliness. The `fusion` subcommand is a loop over
// poll(); tests drive the same class in-process.
//
// Time base: the tracker runs on the DOAs' own times. The output clock is the newest valid time
// seen on Doa or NodeStatus (nodes report status every second even when they hear nothing, so
// tracks keep coasting and ending through silence); FusionDriver reports each tick once the
// reorder window has passed it. Live (Unix) times are rebased to the first whole second seen
// so the driver's tick counter starts near zero; everything written out adds the base back.
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "apps/dds_support.hpp"
#include "apps/fusion_driver.hpp"
#include "apps/fusion_observer.hpp"
#include "apps/track_id_reservation.hpp"
#include "config/site_config.hpp"
#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"

namespace dronetrack::apps {

struct IntakeCounters {
  std::int64_t doa_received = 0;
  std::int64_t doa_accepted = 0;  // passed validation and the engine took it
  std::int64_t status_received = 0;
  // Indexed by dds::SampleProblem: samples ignored before reaching the engine.
  std::int64_t doa_problems[dds::kSampleProblemCount] = {};
  std::int64_t status_problems[dds::kSampleProblemCount] = {};
  std::int64_t doa_rejected_by_engine = 0;  // engine verdicts other than accepted
  std::int64_t tracks_published = 0;
  std::int64_t alerts_published = 0;
  std::int64_t nodes_lost = 0;
  std::int64_t nodes_rejoined = 0;
  // Doa and NodeStatus samples ahead of the site clock (also counted as absurd_time): a node
  // whose clock jumped forward. Re-anchors: the clock followed them (no other node was heard).
  std::int64_t clock_ahead = 0;
  std::int64_t clock_reanchors = 0;

  std::int64_t doa_ignored() const;
};

struct FusionServiceOptions {
  // The site clock is the newest sample time seen, run on by the wall clock since. A sample
  // further ahead of it than this comes from a node whose clock jumped: refused and counted
  // (it would drag every track's output clock along and make every other node's DOAs late).
  // Nodes in step differ by far less (clock sync: ms; DOA latency: < 1 s).
  double max_clock_lead_s = 3.0;
  // ... unless no sample was consistent with the clock for this long (wall time): then every
  // node the site hears has moved on (a site-wide clock step), and the clock follows them.
  std::chrono::milliseconds clock_reanchor_after{5000};
  // Track ids on the wire start above the high-water mark kept in this file (empty: from 1;
  // see TrackIdReservation).
  std::filesystem::path track_id_file;
  // No NodeStatus for this long (wall time) while the writer is still alive: stale anyway
  // (a hung node whose DDS thread still asserts liveliness).
  std::chrono::milliseconds status_silence_limit{3500};
  // Secure site (docs/deployment.md, "DDS Security"): read Doa and NodeStatus from the
  // per-array partitions ("array.ID", each granted only to that array's identity) and refuse a
  // sample whose array id is not the partition's it was written in.
  bool array_partitions = false;
};

class DdsFusionService {
 public:
  // `observers` receive everything the FusionDriver produces, with times in the wire's base
  // (Unix seconds for live nodes, recording seconds for replayed recordings).
  DdsFusionService(const config::SiteConfig& site, const dds::Participant& participant,
                   std::vector<FusionObserver*> observers, FusionServiceOptions options = {});
  ~DdsFusionService();
  DdsFusionService(const DdsFusionService&) = delete;
  DdsFusionService& operator=(const DdsFusionService&) = delete;

  // Waits up to `timeout` for samples, handles everything available, advances the fusion.
  void poll(std::chrono::nanoseconds timeout);
  // Emits the remaining output ticks (at shutdown).
  void finish();

  const IntakeCounters& counters() const { return counters_; }
  const fusion::FusionCounters& engine_counters() const { return driver_.engine().counters(); }
  // False once a node's liveliness was lost (or it went silent), true again when it reports.
  bool node_alive(const std::string& array_id) const;
  // Seconds (wire base) of the newest valid sample, or NaN before the first.
  double latest_time_s() const;

 private:
  class Outputs;  // the observer that rebases times and writes Track/Alert samples

  void take_doas();
  void take_statuses();
  void check_silent_nodes();
  bool plausible_time(std::int64_t time_ns, dds::SampleProblem& problem);
  void mark_stale(const std::string& array_id, const char* why);
  // With array_partitions: true if the sample's writer publishes in `array_id`'s partition.
  bool from_own_partition(dds_entity_t reader, const dds_sample_info_t& info,
                          const std::string& array_id);
  double rebased(std::int64_t time_ns) const;

  std::vector<std::string> array_ids_;
  FusionServiceOptions options_;
  dds::Topic<dronetrack_Doa> doa_topic_;
  dds::Topic<dronetrack_NodeStatus> status_topic_;
  dds::Topic<dronetrack_Track> track_topic_;
  dds::Topic<dronetrack_Alert> alert_topic_;
  dds::Reader<dronetrack_Doa> doa_reader_;
  dds::Reader<dronetrack_NodeStatus> status_reader_;
  dds::Writer<dronetrack_Track> track_writer_;
  dds::Writer<dronetrack_Alert> alert_writer_;
  dds::WaitSet waitset_;
  TrackIdReservation track_ids_;
  std::unique_ptr<Outputs> outputs_;
  FusionDriver driver_;
  IntakeCounters counters_;
  ThrottledWarnings warnings_;

  bool have_time_ = false;
  std::int64_t base_ns_ = 0;
  std::int64_t newest_ns_ = 0;
  std::chrono::steady_clock::time_point newest_at_{};      // when newest_ns_ last moved
  std::chrono::steady_clock::time_point consistent_at_{};  // the last sample the clock took
  doa::DoaMeasurement measurement_;                        // reused: no allocation per sample
  doa::NodeStatus status_;
  // Writer (publication handle) -> its partitions, looked up once per writer.
  std::unordered_map<dds_instance_handle_t, std::vector<std::string>> writer_partitions_;

  struct NodeState {
    bool alive = false;
    doa::NodeStatus last;
    std::chrono::steady_clock::time_point last_report{};
  };
  std::map<std::string, NodeState> nodes_;
};

}  // namespace dronetrack::apps
