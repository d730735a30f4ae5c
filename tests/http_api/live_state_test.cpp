// LiveState: the JSON documents of docs/http_api.md, built from known inputs, and the bounded
// per-client queues.
#include "http_api/live_state.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "doa/pose_sample.hpp"
#include "tests/http_api/test_support.hpp"

namespace dronetrack::http_api::live_state_test {
namespace {

using nlohmann::json;
using test::make_track;
using test::two_array_layout;

void expect_vec3(const json& value, const Eigen::Vector3d& expected) {
  ASSERT_TRUE(value.is_array());
  ASSERT_EQ(value.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(value[i].get<double>(), expected[i], 1e-9) << i;
}

TEST(LiveState, SiteListsArraysWithPoseAndMicsAndZones) {
  LiveState state(two_array_layout());
  const json site = json::parse(state.site_json());
  ASSERT_EQ(site["arrays"].size(), 2u);
  const json& a2 = site["arrays"][1];
  EXPECT_EQ(a2["id"], "A2");
  EXPECT_EQ(a2["index"], 1);
  expect_vec3(a2["position_m"], {40, 0, 1.5});
  EXPECT_DOUBLE_EQ(a2["yaw_deg"].get<double>(), 90.0);
  ASSERT_EQ(a2["mics_m"].size(), 4u);
  expect_vec3(a2["mics_m"][0], {0.1, 0, 0});
  // Yaw 90 turns the array's +x mic to site +y.
  expect_vec3(a2["mics_site_m"][0], {40, 0.1, 1.5});
  ASSERT_EQ(site["zones"].size(), 1u);
  EXPECT_EQ(site["zones"][0]["name"], "pad");
  EXPECT_EQ(site["zones"][0]["polygon_m"].size(), 4u);
  EXPECT_DOUBLE_EQ(site["zones"][0]["polygon_m"][2][0].get<double>(), 30.0);
  EXPECT_DOUBLE_EQ(site["zones"][0]["altitude_max_m"].get<double>(), 120.0);
  EXPECT_DOUBLE_EQ(site["speed_of_sound_mps"].get<double>(), 343.0);
}

TEST(LiveState, TracksCarrySpecFieldsCovarianceHeadingAndArrays) {
  LiveState state(two_array_layout());
  // Flying east at 3 m/s and climbing 4 m/s: compass heading 90, speed 5.
  state.publish_tracks(12.5, {make_track(7, 12.5, {20, 25, 40}, {3, 0, 4})});
  const json doc = json::parse(state.tracks_json());
  EXPECT_DOUBLE_EQ(doc["t"].get<double>(), 12.5);
  ASSERT_EQ(doc["tracks"].size(), 1u);
  const json& t = doc["tracks"][0];
  EXPECT_EQ(t["id"], 7);
  EXPECT_DOUBLE_EQ(t["t"].get<double>(), 12.5);
  expect_vec3(t["position_m"], {20, 25, 40});
  expect_vec3(t["velocity_mps"], {3, 0, 4});
  expect_vec3(t["acceleration_mps2"], {0, 0, 0});
  expect_vec3(t["position_std_m"], {2, 3, 4});
  EXPECT_EQ(t["status"], "confirmed");
  EXPECT_DOUBLE_EQ(t["covariance_xy_m2"][0][0].get<double>(), 4.0);
  EXPECT_DOUBLE_EQ(t["covariance_xy_m2"][0][1].get<double>(), 1.5);
  EXPECT_DOUBLE_EQ(t["covariance_xy_m2"][1][1].get<double>(), 9.0);
  EXPECT_EQ(t["contributing_arrays"], json::array({"A1", "A2"}));
  EXPECT_NEAR(t["speed_mps"].get<double>(), 5.0, 1e-12);
  EXPECT_NEAR(t["ground_speed_mps"].get<double>(), 3.0, 1e-12);
  EXPECT_NEAR(t["heading_deg"].get<double>(), 90.0, 1e-9);
}

TEST(LiveState, HeadingIsCompassClockwiseFromNorth) {
  LiveState state(two_array_layout());
  const std::vector<std::pair<Eigen::Vector3d, double>> cases = {
      {{0, 1, 0}, 0.0}, {{1, 1, 0}, 45.0}, {{0, -2, 0}, 180.0}, {{-1, 0, 0}, 270.0}};
  for (const auto& [velocity, heading] : cases) {
    state.publish_tracks(1.0, {make_track(1, 1.0, {0, 0, 10}, velocity)});
    const json t = json::parse(state.tracks_json())["tracks"][0];
    EXPECT_NEAR(t["heading_deg"].get<double>(), heading, 1e-9) << velocity.transpose();
  }
}

TEST(LiveState, CurrentTracksAreTheLastPublishedSetAndHistoryKeepsTrails) {
  LiveState state(two_array_layout());
  for (int k = 0; k < 30; ++k) {
    const double t = 0.1 * k;
    std::vector<fusion::TrackReport> tracks{make_track(1, t, {double(k), 0, 10}, {10, 0, 0})};
    if (k >= 20) tracks.push_back(make_track(2, t, {0, double(k), 20}, {0, 10, 0}));
    state.publish_tracks(t, tracks);
  }
  state.publish_tracks(3.0, {make_track(2, 3.0, {0, 30, 20}, {0, 10, 0})});
  const json current = json::parse(state.tracks_json());
  ASSERT_EQ(current["tracks"].size(), 1u);
  EXPECT_EQ(current["tracks"][0]["id"], 2);

  const json all = json::parse(state.history_json(-1e300));
  EXPECT_EQ(all["columns"], json::array({"t", "x_m", "y_m", "z_m"}));
  ASSERT_EQ(all["tracks"].size(), 2u);
  EXPECT_EQ(all["tracks"][0]["id"], 1);
  EXPECT_EQ(all["tracks"][0]["points"].size(), 30u);
  EXPECT_EQ(all["tracks"][1]["points"].size(), 11u);
  const json& p = all["tracks"][0]["points"][5];
  EXPECT_NEAR(p[0].get<double>(), 0.5, 1e-12);
  EXPECT_DOUBLE_EQ(p[1].get<double>(), 5.0);
  EXPECT_DOUBLE_EQ(p[3].get<double>(), 10.0);

  // `since` is exclusive: strictly later points only.
  const json later = json::parse(state.history_json(2.5));
  ASSERT_EQ(later["tracks"].size(), 2u);
  EXPECT_EQ(later["tracks"][0]["points"].size(), 4u);  // 2.6 .. 2.9
  EXPECT_EQ(later["tracks"][1]["points"].size(), 5u);  // 2.6 .. 3.0
  EXPECT_TRUE(json::parse(state.history_json(3.0))["tracks"].empty());
}

TEST(LiveState, HistoryIsBoundedInPointsAndTime) {
  LiveStateLimits limits;
  limits.history_points_per_track = 50;
  limits.history_window_s = 20.0;
  LiveState state(two_array_layout(), limits);
  for (int k = 0; k < 200; ++k) {
    const double t = 0.1 * k;
    state.publish_tracks(t, {make_track(1, t, {0, 0, 10}, {1, 0, 0})});
  }
  json doc = json::parse(state.history_json(-1e300));
  ASSERT_EQ(doc["tracks"][0]["points"].size(), 50u);
  EXPECT_NEAR(doc["tracks"][0]["points"][0][0].get<double>(), 15.0, 1e-9);
  // Track 1 ends; 25 s later its trail has aged out entirely.
  state.publish_tracks(45.0, {make_track(2, 45.0, {0, 0, 10}, {1, 0, 0})});
  doc = json::parse(state.history_json(-1e300));
  ASSERT_EQ(doc["tracks"].size(), 1u);
  EXPECT_EQ(doc["tracks"][0]["id"], 2);
}

TEST(LiveState, NodesAreStaleWithoutRecentStatusOrWhenNotAlive) {
  LiveState state(two_array_layout());
  doa::NodeStatus a1;
  a1.array_id = "A1";
  a1.time_s = 10.0;
  a1.level_dbfs = -31.5;
  a1.clipped_samples = 3;
  a1.overruns = 2;
  a1.channels = {{0, 0, 0, 0, -30.0},
                 {doa::health_flag(doa::HealthProblem::non_finite),
                  doa::health_flag(doa::HealthProblem::non_finite) |
                      doa::health_flag(doa::HealthProblem::dc_offset),
                  480, 3, -120.0}};
  a1.channels[0].delay_offset_us = 22.5;
  a1.channels[0].delay_std_us = 2.5;  // judged; channel 1 keeps the default: not judged
  state.publish_node(a1);
  doa::DoaMeasurement d;
  d.array_id = "A1";
  d.array_index = 0;
  d.time_s = 10.2;
  d.direction = Eigen::Vector3d(0, 1, 1).normalized();
  d.quality = 0.8;
  state.publish_doa(d);
  d.source_index = 1;
  d.direction = Eigen::Vector3d(1, 0, 0);
  state.publish_doa(d);
  state.set_time(12.9);

  json doc = json::parse(state.nodes_json());
  EXPECT_DOUBLE_EQ(doc["t"].get<double>(), 12.9);
  ASSERT_EQ(doc["nodes"].size(), 2u);
  const json& n1 = doc["nodes"][0];
  EXPECT_EQ(n1["array"], "A1");
  EXPECT_EQ(n1["state"], "alive");
  EXPECT_EQ(n1["stale"], false);
  EXPECT_TRUE(n1["stale_reason"].is_null());
  EXPECT_NEAR(n1["status_age_s"].get<double>(), 2.9, 1e-9);
  EXPECT_DOUBLE_EQ(n1["status"]["level_dbfs"].get<double>(), -31.5);
  EXPECT_EQ(n1["status"]["clipped_samples"], 3);
  EXPECT_EQ(n1["status"]["overruns"], 2);
  // Per-channel audio health, problems by name.
  const json& channels = n1["status"]["channels"];
  ASSERT_EQ(channels.size(), 2u);
  EXPECT_EQ(channels[0]["problems"], json::array());
  EXPECT_EQ(channels[1]["problems"], json::array({"non_finite"}));
  EXPECT_EQ(channels[1]["problems_seen"], json::array({"non_finite", "dc_offset"}));
  EXPECT_EQ(channels[1]["non_finite_samples"], 480);
  EXPECT_EQ(channels[1]["clipped_samples"], 3);
  EXPECT_DOUBLE_EQ(channels[1]["rms_dbfs"].get<double>(), -120.0);
  EXPECT_DOUBLE_EQ(channels[0]["delay_offset_us"].get<double>(), 22.5);
  EXPECT_DOUBLE_EQ(channels[0]["delay_std_us"].get<double>(), 2.5);
  EXPECT_TRUE(channels[1]["delay_std_us"].is_null());
  ASSERT_EQ(n1["doa"].size(), 2u);
  EXPECT_EQ(n1["doa"][0]["source_index"], 0);
  EXPECT_NEAR(n1["doa"][0]["azimuth_deg"].get<double>(), 90.0, 1e-9);
  EXPECT_NEAR(n1["doa"][0]["elevation_deg"].get<double>(), 45.0, 1e-9);
  EXPECT_EQ(n1["doa"][0]["ambiguity"], "none");
  const json& n2 = doc["nodes"][1];
  EXPECT_EQ(n2["array"], "A2");
  EXPECT_EQ(n2["state"], "stale");
  EXPECT_EQ(n2["stale_reason"], "no_status");
  EXPECT_TRUE(n2["status"].is_null());

  state.set_time(13.1);  // 3.1 s without a status
  doc = json::parse(state.nodes_json());
  EXPECT_EQ(doc["nodes"][0]["state"], "stale");
  EXPECT_EQ(doc["nodes"][0]["stale_reason"], "timeout");

  a1.time_s = 13.1;
  a1.alive = false;
  state.publish_node(a1);
  doc = json::parse(state.nodes_json());
  EXPECT_EQ(doc["nodes"][0]["stale_reason"], "not_alive");

  // A node the layout does not know is listed rather than hidden.
  doa::NodeStatus stray;
  stray.array_id = "X9";
  stray.time_s = 13.1;
  state.publish_node(stray);
  doc = json::parse(state.nodes_json());
  ASSERT_EQ(doc["nodes"].size(), 3u);
  EXPECT_EQ(doc["nodes"][2]["array"], "X9");
  EXPECT_EQ(doc["nodes"][2]["state"], "alive");
}

// A moving two-mic array (issue 15): its nodes entry carries the latest pose and a path thinned
// to a point per 2 m (or 5 s), and its DOAs say what was measured (the cone).
TEST(LiveState, MovingArrayHasAPoseAPathAndConeDoas) {
  LiveState state(two_array_layout());
  for (int k = 0; k <= 100; ++k) {  // 10 s at 10 Hz, 1.5 m/s east: 15 m
    doa::DoaMeasurement doa;
    doa.array_id = "A2";
    doa.array_index = 1;
    doa.time_s = 0.1 * k;
    doa.ambiguity = doa::DoaAmbiguity::cone;
    doa.ambiguity_axis = Eigen::Vector3d::UnitX();
    doa.cone_angle_rad = 1.0;
    doa.cone_angle_variance_rad2 = 1e-4;
    doa.pose = {Eigen::Vector3d(40.0 + 0.15 * k, 0, -2),
                Eigen::Quaterniond(doa::attitude_to_site(30, 0, 0)), true};
    state.publish_doa(doa);
  }
  const json nodes = json::parse(state.nodes_json());
  const json& a2 = nodes["nodes"][1];
  ASSERT_EQ(a2["array"], "A2");
  EXPECT_DOUBLE_EQ(a2["pose"]["t"].get<double>(), 10.0);
  expect_vec3(a2["pose"]["centre_m"], {55, 0, -2});
  EXPECT_NEAR(a2["pose"]["attitude_deg"][0].get<double>(), 30.0, 1e-9);
  // Points at 0, 2.1, 4.2, ... 14.7 m (every 14th DOA: 0.15 m each, the first >= 2 m).
  ASSERT_EQ(a2["path"].size(), 8u);
  EXPECT_NEAR(a2["path"][1][1].get<double>(), 40.0 + 14 * 0.15, 1e-9);
  const json& doa = a2["doa"][0];
  EXPECT_NEAR(doa["cone"]["angle_deg"].get<double>(), 180.0 / M_PI, 1e-9);
  expect_vec3(doa["cone"]["axis"], {1, 0, 0});
  expect_vec3(doa["pose"]["centre_m"], {55, 0, -2});
  // A fixed array has neither.
  EXPECT_TRUE(nodes["nodes"][0]["pose"].is_null());
  EXPECT_TRUE(nodes["nodes"][0]["path"].empty());
}

TEST(LiveState, TimeNeverGoesBackwards) {
  LiveState state(two_array_layout());
  state.set_time(5.0);
  state.set_time(4.0);
  state.set_time(std::nan(""));
  EXPECT_DOUBLE_EQ(state.time_s(), 5.0);
}

TEST(LiveState, AlertsKeepOrderAndFilterBySince) {
  LiveStateLimits limits;
  limits.max_alerts = 3;
  LiveState state(two_array_layout(), limits);
  for (int k = 0; k < 5; ++k) {
    fusion::ZoneEvent e;
    e.zone = "pad";
    e.track_id = k;
    e.entered = k % 2 == 0;
    e.time_s = 10.0 + k;
    e.position_m = {20, 20, 30};
    state.publish_alert(e);
  }
  json doc = json::parse(state.alerts_json(-1e300));
  ASSERT_EQ(doc["alerts"].size(), 3u);
  EXPECT_EQ(doc["alerts"][0]["track_id"], 2);
  EXPECT_EQ(doc["alerts"][0]["zone"], "pad");
  EXPECT_EQ(doc["alerts"][0]["event"], "entered");
  EXPECT_EQ(doc["alerts"][1]["entered"], false);
  EXPECT_EQ(doc["alerts"][1]["event"], "left");
  expect_vec3(doc["alerts"][2]["position_m"], {20, 20, 30});
  EXPECT_EQ(json::parse(state.alerts_json(13.0))["alerts"].size(), 1u);
}

TEST(LiveState, SubscribersGetASnapshotThenEveryPublishedEvent) {
  LiveState state(two_array_layout());
  state.publish_tracks(1.0, {make_track(4, 1.0, {1, 2, 3}, {0, 0, 0})});
  auto queue = state.subscribe();
  fusion::ZoneEvent e;
  e.zone = "pad";
  e.track_id = 4;
  state.publish_alert(e);
  std::vector<std::shared_ptr<const std::string>> events;
  ASSERT_TRUE(queue->pop_all(events, 100));
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[0]->rfind("event: tracks\ndata: {", 0), 0u);
  EXPECT_NE(events[0]->find("\"id\":4"), std::string::npos);
  EXPECT_EQ(events[1]->rfind("event: nodes\n", 0), 0u);
  EXPECT_EQ(events[2]->rfind("event: alert\n", 0), 0u);
  EXPECT_EQ(events[2]->substr(events[2]->size() - 2), "\n\n");
  state.unsubscribe(queue);
  EXPECT_EQ(state.subscriber_count(), 0u);
  EXPECT_FALSE(queue->pop_all(events, 0));
}

TEST(LiveState, AFullQueueDropsItsClientWithoutBlockingThePublisher) {
  LiveStateLimits limits;
  limits.stream_queue_events = 8;
  LiveState state(two_array_layout(), limits);
  auto stuck = state.subscribe();  // never popped
  auto reader = state.subscribe();
  std::vector<std::shared_ptr<const std::string>> events;
  for (int k = 0; k < 20; ++k) {
    state.publish_tracks(k, {make_track(1, k, {0, 0, 10}, {1, 0, 0})});
    events.clear();
    ASSERT_TRUE(reader->pop_all(events, 0)) << k;
  }
  EXPECT_TRUE(stuck->dropped());
  EXPECT_FALSE(stuck->pop_all(events, 0));
  EXPECT_EQ(state.subscriber_count(), 1u);
  EXPECT_EQ(state.dropped_clients(), 1);
}

}  // namespace
}  // namespace dronetrack::http_api::live_state_test
