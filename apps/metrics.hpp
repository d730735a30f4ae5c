#pragma once
// What `fusion`, `replay --http` and `node --metrics-listen` expose on GET /metrics (Prometheus
// text; docs/http_api.md "Metrics"). Every counter is read from state the code already keeps
// (the engine's FusionCounters, the DDS intake's IntakeCounters, each node's NodeStatus and
// NodeDiagnostics), copied in by the thread that owns it; the tallies kept here (tracks by
// status and class, alerts, the latency histogram) are of the fusion's outputs as observed.
// Thread-safe like LiveState: the owner thread updates under a short lock, the server's threads
// render under the same lock. Updates do not allocate.
#include <array>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "apps/fusion_observer.hpp"
#include "doa/node_pipeline.hpp"
#include "doa/node_status.hpp"
#include "fusion/fusion_engine.hpp"
#include "http_api/metrics_text.hpp"

namespace dronetrack::apps {

struct IntakeCounters;

// The fusion side (replay and the DDS fusion): an observer of the driver's outputs.
class FusionMetrics : public FusionObserver {
 public:
  // `role`: the build-info label ("fusion", "replay"). `array_ids`: the site's, in order.
  FusionMetrics(std::string role, std::vector<std::string> array_ids);

  // The wall clock in stream seconds (Unix time for live nodes; seconds since the paced start in
  // `replay --realtime`); unset or NaN: the stream has no wall time and no latency is observed.
  void set_stream_clock(std::function<double()> wall_stream_s);
  void set_intake_counters(const IntakeCounters& counters);  // the DDS fusion, after each poll

  void on_counters(const fusion::FusionCounters& counters) override;
  void on_node_status(const doa::NodeStatus& status) override;
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) override;
  void on_zone_event(const fusion::ZoneEvent& event) override;

  std::string text() const;  // the /metrics body

 private:
  struct NodeCounts {
    std::int64_t overruns = 0;
    std::int64_t clipped_samples = 0;
    std::int64_t non_finite_samples = 0;
    bool reported = false;
  };
  static constexpr std::size_t kStatuses = 3;  // fusion::TrackStatus
  static constexpr std::size_t kClasses = 4;   // fusion::TrackClass
  static constexpr std::size_t kEvents = 3;    // fusion::ZoneEventKind
  static constexpr std::size_t kProblems = 8;  // dds::SampleProblem

  const std::string role_;
  const std::vector<std::string> array_ids_;
  mutable std::mutex mutex_;
  std::function<double()> wall_stream_s_;
  fusion::FusionCounters engine_;
  bool have_intake_ = false;
  std::array<std::int64_t, kProblems> doa_problems_{};
  std::array<std::int64_t, kProblems> status_problems_{};
  std::int64_t doa_received_ = 0;
  std::vector<NodeCounts> nodes_;  // per array_ids_
  std::array<std::array<std::int64_t, kClasses>, kStatuses> tracks_{};
  std::int64_t ticks_ = 0;
  std::array<std::int64_t, kEvents> alerts_{};
  http_api::Histogram latency_s_;
};

// The node side (`node --metrics-listen`).
class NodeMetrics {
 public:
  explicit NodeMetrics(std::string array_id);
  // The node loop, after each block: what it published, what its pipeline counted.
  void update(std::int64_t doas_published, std::int64_t write_failures,
              const doa::NodeDiagnostics& diagnostics, std::int64_t overruns);
  std::string text() const;

 private:
  const std::string array_id_;
  mutable std::mutex mutex_;
  std::int64_t doas_published_ = 0;
  std::int64_t write_failures_ = 0;
  std::int64_t overruns_ = 0;
  doa::NodeDiagnostics diagnostics_;
};

}  // namespace dronetrack::apps
