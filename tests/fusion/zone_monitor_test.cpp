#include "fusion/zone_monitor.hpp"

#include <gtest/gtest.h>

namespace dronetrack::fusion::zone_monitor_test {
namespace {

Zone yard() { return {"yard", {{-50, -50}, {50, -50}, {50, 50}, {-50, 50}}, 0.0, 150.0}; }

TrackReport track_at(int id, Eigen::Vector3d position, TrackStatus status,
                     TrackClass track_class = TrackClass::drone, double confirmed_s = 10.0) {
  TrackReport report;
  report.id = id;
  report.position_m = position;
  report.status = status;
  report.track_class = track_class;
  report.confirmed_s = status == TrackStatus::tentative ? -1.0 : confirmed_s;
  return report;
}

std::vector<ZoneEvent> of_kind(const std::vector<ZoneEvent>& events, ZoneEventKind kind) {
  std::vector<ZoneEvent> out;
  for (const auto& event : events)
    if (event.kind == kind) out.push_back(event);
  return out;
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
  // Its first report as a confirmed drone is a class change (from unknown), no zone event.
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, ZoneEventKind::class_changed);
  events.clear();
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
  ASSERT_EQ(of_kind(events, ZoneEventKind::entered).size(), 1u);
  events.clear();
  monitor.update(6.0, {}, events);  // deleted while inside
  ASSERT_EQ(events.size(), 1u);
  EXPECT_FALSE(events[0].entered);
  EXPECT_EQ(events[0].track_id, 2);
}

// Issue 14's alert policy: only drones alert (by default), and only once confirmed for
// min_confirmed_s; a class change is reported, and a track that stops being a drone inside a
// zone leaves it.
TEST(ZoneMonitor, OnlyTheAlertPolicysClassesAlertAndClassChangesAreReported) {
  ZoneMonitor monitor({yard()}, AlertPolicy{{TrackClass::drone}, 2.0});
  std::vector<ZoneEvent> events;
  monitor.update(0.0,
                 {track_at(1, {0, 0, 1}, TrackStatus::confirmed, TrackClass::ground),
                  track_at(2, {10, 0, 300}, TrackStatus::confirmed, TrackClass::aircraft),
                  track_at(3, {0, 10, 30}, TrackStatus::confirmed, TrackClass::unknown),
                  track_at(4, {0, -10, 30}, TrackStatus::confirmed, TrackClass::drone, 1.0)},
                 events);
  EXPECT_TRUE(of_kind(events, ZoneEventKind::entered).empty());  // drone 4 confirmed only 1 s
  ASSERT_EQ(of_kind(events, ZoneEventKind::class_changed).size(), 3u);  // 1, 2, 4 (3 stays unknown)
  events.clear();
  monitor.update(1.0,
                 {track_at(1, {0, 0, 1}, TrackStatus::confirmed, TrackClass::ground),
                  track_at(3, {0, 10, 30}, TrackStatus::confirmed, TrackClass::drone),
                  track_at(4, {0, -10, 30}, TrackStatus::confirmed, TrackClass::drone, 2.0)},
                 events);
  const auto entered = of_kind(events, ZoneEventKind::entered);
  ASSERT_EQ(entered.size(), 2u);
  EXPECT_EQ(entered[0].track_class, TrackClass::drone);
  const auto changed = of_kind(events, ZoneEventKind::class_changed);
  ASSERT_EQ(changed.size(), 1u);
  EXPECT_EQ(changed[0].track_id, 3);
  EXPECT_EQ(changed[0].previous_class, TrackClass::unknown);
  EXPECT_EQ(changed[0].track_class, TrackClass::drone);
  events.clear();
  // Track 3 turns out to be a ground source while inside: its alert ends.
  monitor.update(2.0,
                 {track_at(3, {0, 10, 2}, TrackStatus::confirmed, TrackClass::ground),
                  track_at(4, {0, -10, 30}, TrackStatus::confirmed, TrackClass::drone, 3.0)},
                 events);
  const auto left = of_kind(events, ZoneEventKind::left);
  ASSERT_EQ(left.size(), 1u);
  EXPECT_EQ(left[0].track_id, 3);
}

}  // namespace
}  // namespace dronetrack::fusion::zone_monitor_test
