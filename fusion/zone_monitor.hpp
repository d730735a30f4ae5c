#pragma once
// Turns track positions into zone entry/exit events: a track is inside a zone when its x-y
// position is inside the polygon and its altitude inside the band.
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "fusion/fusion_params.hpp"
#include "fusion/track_report.hpp"

namespace dronetrack::fusion {

struct ZoneEvent {
  std::string zone;
  int track_id = 0;
  bool entered = true;  // false: left (or the track was deleted while inside)
  double time_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
};

bool zone_contains(const Zone& zone, const Eigen::Vector3d& position_m);

class ZoneMonitor {
 public:
  explicit ZoneMonitor(std::vector<Zone> zones);
  // `tracks` are all live tracks at time_s. Tracks that are tentative do not alert; a track that
  // disappears while inside produces a "left" event.
  void update(double time_s, const std::vector<TrackReport>& tracks, std::vector<ZoneEvent>& out);
  const std::vector<Zone>& zones() const { return zones_; }

 private:
  std::vector<Zone> zones_;
  std::set<std::pair<std::size_t, int>> inside_;  // (zone index, track id)
};

}  // namespace dronetrack::fusion
