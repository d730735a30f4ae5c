#include "fusion/zone_monitor.hpp"

#include <algorithm>

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

const char* to_string(ZoneEventKind kind) {
  switch (kind) {
    case ZoneEventKind::left:
      return "left";
    case ZoneEventKind::entered:
      return "entered";
    case ZoneEventKind::class_changed:
      return "class_changed";
  }
  return "left";
}

ZoneMonitor::ZoneMonitor(std::vector<Zone> zones, AlertPolicy policy)
    : zones_(std::move(zones)), policy_(std::move(policy)) {}

bool ZoneMonitor::may_alert(const TrackReport& track) const {
  if (track.status == TrackStatus::tentative || track.confirmed_s < policy_.min_confirmed_s)
    return false;
  return std::find(policy_.classes.begin(), policy_.classes.end(), track.track_class) !=
         policy_.classes.end();
}

void ZoneMonitor::update(double time_s, const std::vector<TrackReport>& tracks,
                         std::vector<ZoneEvent>& out) {
  std::map<int, TrackClass> now_classes;
  for (const auto& track : tracks) {
    if (track.status == TrackStatus::tentative) continue;
    now_classes.emplace(track.id, track.track_class);
    const auto before = class_of_track_.find(track.id);
    const TrackClass previous =
        before != class_of_track_.end() ? before->second : TrackClass::unknown;
    if (previous != track.track_class) {
      ZoneEvent event;
      event.track_id = track.id;
      event.entered = false;
      event.time_s = time_s;
      event.position_m = track.position_m;
      event.kind = ZoneEventKind::class_changed;
      event.track_class = track.track_class;
      event.previous_class = previous;
      out.push_back(event);
    }
  }
  class_of_track_ = std::move(now_classes);

  std::set<std::pair<std::size_t, int>> now_inside;
  for (std::size_t zone_index = 0; zone_index < zones_.size(); ++zone_index) {
    for (const auto& track : tracks) {
      if (!may_alert(track)) continue;
      if (!zone_contains(zones_[zone_index], track.position_m)) continue;
      now_inside.emplace(zone_index, track.id);
      if (!inside_.count({zone_index, track.id})) {
        ZoneEvent event{zones_[zone_index].name, track.id, true, time_s, track.position_m};
        event.kind = ZoneEventKind::entered;
        event.track_class = track.track_class;
        out.push_back(event);
      }
    }
  }
  for (const auto& [zone_index, track_id] : inside_) {
    if (now_inside.count({zone_index, track_id})) continue;
    ZoneEvent event{zones_[zone_index].name, track_id, false, time_s, Eigen::Vector3d::Zero()};
    event.kind = ZoneEventKind::left;
    for (const auto& track : tracks) {
      if (track.id != track_id) continue;
      event.position_m = track.position_m;
      event.track_class = track.track_class;
    }
    out.push_back(event);
  }
  inside_ = std::move(now_inside);
}

}  // namespace dronetrack::fusion
