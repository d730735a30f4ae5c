#pragma once
// Everything the fusion side produces, as callbacks. Replay and the DDS fusion process drive the
// same FusionDriver; outputs (JSON-lines files, the HTTP live state, DDS writers) are observers.
#include <vector>

#include "doa/doa_measurement.hpp"
#include "doa/node_status.hpp"
#include "fusion/fusion_engine.hpp"
#include "fusion/track_report.hpp"
#include "fusion/zone_monitor.hpp"

namespace dronetrack::apps {

class FusionObserver {
 public:
  virtual ~FusionObserver() = default;
  // False for an observer that takes only DOAs and node status: when no observer of a run wants
  // tracks, FusionDriver checks the DOAs without running the tracker (a DOA-only replay).
  virtual bool wants_tracks() const { return true; }
  virtual void on_doa(const doa::DoaMeasurement& /*doa*/) {}
  virtual void on_node_status(const doa::NodeStatus& /*status*/) {}
  // All live tracks at one output tick.
  virtual void on_tracks(double /*time_s*/, const std::vector<fusion::TrackReport>& /*tracks*/) {}
  virtual void on_zone_event(const fusion::ZoneEvent& /*event*/) {}
  // The engine's counters after each output tick (the metrics read them; nothing counts twice).
  virtual void on_counters(const fusion::FusionCounters& /*counters*/) {}
  // Stream time advanced (for staleness and pacing displays).
  virtual void on_time(double /*time_s*/) {}
};

}  // namespace dronetrack::apps
