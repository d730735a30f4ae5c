#pragma once
// Turns track positions into zone entry/exit events: a track is inside a zone when its x-y
// position is inside the polygon and its altitude inside the band.
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "fusion/fusion_params.hpp"
#include "fusion/track_report.hpp"

namespace dronetrack::fusion {

enum class ZoneEventKind : std::uint8_t { left = 0, entered = 1, class_changed = 2 };
const char* to_string(ZoneEventKind kind);

struct ZoneEvent {
  std::string zone;  // empty for class_changed (a track's, not a zone's event)
  int track_id = 0;
  bool entered = true;  // false: left (or the track was deleted while inside); kind says more
  double time_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  ZoneEventKind kind = ZoneEventKind::entered;
  TrackClass track_class = TrackClass::unknown;
  TrackClass previous_class = TrackClass::unknown;  // class_changed only
};

// The event's kind with `entered` authoritative for zone events (producers that only set
// `entered` stay correct).
inline ZoneEventKind kind_of(const ZoneEvent& event) {
  if (event.kind == ZoneEventKind::class_changed) return event.kind;
  return event.entered ? ZoneEventKind::entered : ZoneEventKind::left;
}

// Which tracks may raise zone alerts (issue 14): only these classes, and only once confirmed
// this long (a track's class settles in its first seconds).
struct AlertPolicy {
  std::vector<TrackClass> classes{TrackClass::drone};
  double min_confirmed_s = 1.0;
};

bool zone_contains(const Zone& zone, const Eigen::Vector3d& position_m);

class ZoneMonitor {
 public:
  explicit ZoneMonitor(std::vector<Zone> zones, AlertPolicy policy = {});
  // `tracks` are all live tracks at time_s. Only tracks the policy allows alert; a track that
  // disappears while inside, or stops being allowed (its class changed), produces a "left"
  // event. Every change of a confirmed track's class is a class_changed event.
  void update(double time_s, const std::vector<TrackReport>& tracks, std::vector<ZoneEvent>& out);
  const std::vector<Zone>& zones() const { return zones_; }

 private:
  bool may_alert(const TrackReport& track) const;
  std::vector<Zone> zones_;
  AlertPolicy policy_;
  std::set<std::pair<std::size_t, int>> inside_;  // (zone index, track id)
  std::map<int, TrackClass> class_of_track_;      // last class reported per confirmed track
};

}  // namespace dronetrack::fusion
