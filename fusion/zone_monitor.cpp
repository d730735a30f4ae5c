#include "fusion/zone_monitor.hpp"

namespace dronetrack::fusion {

bool zone_contains(const Zone& zone, const Eigen::Vector3d& position_m) {
  if (position_m.z() < zone.altitude_min_m || position_m.z() > zone.altitude_max_m) return false;
  // Even-odd ray casting along +x.
  bool inside = false;
  const auto& polygon = zone.polygon_m;
  for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[j];
    if ((a.y() > position_m.y()) != (b.y() > position_m.y())) {
      const double crossing_x =
          a.x() + (position_m.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (position_m.x() < crossing_x) inside = !inside;
    }
  }
  return inside;
}

ZoneMonitor::ZoneMonitor(std::vector<Zone> zones) : zones_(std::move(zones)) {}

void ZoneMonitor::update(double time_s, const std::vector<TrackReport>& tracks,
                         std::vector<ZoneEvent>& out) {
  std::set<std::pair<std::size_t, int>> now_inside;
  for (std::size_t zone_index = 0; zone_index < zones_.size(); ++zone_index) {
    for (const auto& track : tracks) {
      if (track.status == TrackStatus::tentative) continue;
      if (!zone_contains(zones_[zone_index], track.position_m)) continue;
      now_inside.emplace(zone_index, track.id);
      if (!inside_.count({zone_index, track.id})) {
        out.push_back({zones_[zone_index].name, track.id, true, time_s, track.position_m});
      }
    }
  }
  for (const auto& [zone_index, track_id] : inside_) {
    if (now_inside.count({zone_index, track_id})) continue;
    Eigen::Vector3d last_position = Eigen::Vector3d::Zero();
    for (const auto& track : tracks) {
      if (track.id == track_id) last_position = track.position_m;
    }
    out.push_back({zones_[zone_index].name, track_id, false, time_s, last_position});
  }
  inside_ = std::move(now_inside);
}

}  // namespace dronetrack::fusion
