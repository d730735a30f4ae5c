#include "fusion/zone_monitor.hpp"

#include <gtest/gtest.h>

namespace dronetrack::fusion {
namespace {

Zone yard() { return {"yard", {{-50, -50}, {50, -50}, {50, 50}, {-50, 50}}, 0.0, 150.0}; }

TrackReport track_at(int id, Eigen::Vector3d position, TrackStatus status) {
  TrackReport report;
  report.id = id;
  report.position_m = position;
  report.status = status;
  return report;
}

TEST(ZoneMonitor, ContainsRespectsPolygonAndAltitude) {
  EXPECT_TRUE(zone_contains(yard(), {0, 0, 30}));
  EXPECT_FALSE(zone_contains(yard(), {60, 0, 30}));
  EXPECT_FALSE(zone_contains(yard(), {0, 0, 200}));
  const Zone concave{"L", {{0, 0}, {10, 0}, {10, 10}, {5, 10}, {5, 5}, {0, 5}}, -1e9, 1e9};
  EXPECT_TRUE(zone_contains(concave, {2, 2, 0}));
  EXPECT_FALSE(zone_contains(concave, {2, 8, 0}));
}

TEST(ZoneMonitor, EnterLeaveAndDisappear) {
  ZoneMonitor monitor({yard()});
  std::vector<ZoneEvent> events;
  monitor.update(0.0, {track_at(1, {-80, 0, 30}, TrackStatus::confirmed)}, events);
  EXPECT_TRUE(events.empty());
  monitor.update(1.0, {track_at(1, {-40, 0, 30}, TrackStatus::confirmed)}, events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_TRUE(events[0].entered);
  EXPECT_EQ(events[0].track_id, 1);
  EXPECT_EQ(events[0].zone, "yard");
  events.clear();
  monitor.update(2.0, {track_at(1, {-30, 0, 30}, TrackStatus::coasting)}, events);
  EXPECT_TRUE(events.empty());  // still inside: no repeat
  monitor.update(3.0, {track_at(1, {70, 0, 30}, TrackStatus::confirmed)}, events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_FALSE(events[0].entered);
  events.clear();
  // Tentative tracks never alert.
  monitor.update(4.0, {track_at(2, {0, 0, 30}, TrackStatus::tentative)}, events);
  EXPECT_TRUE(events.empty());
  monitor.update(5.0, {track_at(2, {0, 0, 30}, TrackStatus::confirmed)}, events);
  ASSERT_EQ(events.size(), 1u);
  events.clear();
  monitor.update(6.0, {}, events);  // deleted while inside
  ASSERT_EQ(events.size(), 1u);
  EXPECT_FALSE(events[0].entered);
  EXPECT_EQ(events[0].track_id, 2);
}

}  // namespace
}  // namespace dronetrack::fusion
