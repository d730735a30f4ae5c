// The live node's pose stamping (issue 15): a DOA waits until the ArrayPose stream brackets its
// time, is turned to the heading at that time, and is dropped (counted) when its pose cannot
// come any more: stream past it, a gap, a turn too fast, a refused sample. Never a crash.
#include "apps/live_pose_stamper.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "doa/array_geometry.hpp"

namespace dronetrack::apps {
namespace {

doa::ArrayGeometry level_pair() {
  return doa::ArrayGeometry{.id = std::string(2, 'M'),
                            .mics_m = {{-0.5, 0.0, 0.0}, {0.5, 0.0, 0.0}}};
}

// A DOA along the array's +x at `time_s`, as the pipeline gives it (the fixed, level pose).
doa::DoaMeasurement doa_at(double time_s, const doa::ArrayGeometry& geometry) {
  doa::DoaMeasurement doa;
  doa.time_s = time_s;
  doa.direction = Eigen::Vector3d::UnitX();
  doa.pose = doa::fixed_stamp(geometry);
  return doa;
}

doa::PoseSample heading(double time_s, double yaw_deg, double x_m = 0.0) {
  return {time_s, {x_m, 0.0, 0.0}, yaw_deg, 0.0, 0.0};
}

TEST(LivePoseStamper, WaitsForThePoseThenTurnsToTheHeadingAtItsTime) {
  const doa::ArrayGeometry geometry = level_pair();
  LivePoseStamper stamper(geometry, 1.0);
  std::vector<doa::DoaMeasurement> doas{doa_at(0.25, geometry)};
  std::vector<doa::DoaMeasurement> ready;
  stamper.add_doas(doas);
  EXPECT_TRUE(doas.empty());
  stamper.add_pose(heading(0.0, 10.0, 0.0));
  stamper.release(0.4, ready);  // the pose after 0.25 s has not come yet: waits
  EXPECT_TRUE(ready.empty());
  EXPECT_EQ(stamper.pending(), 1U);
  stamper.add_pose(heading(0.5, 30.0, 2.0));
  stamper.release(0.6, ready);
  ASSERT_EQ(ready.size(), 1U);
  // Half way: heading 20 deg, origin (1, 0, 0).
  EXPECT_NEAR(doa::azimuth_deg(ready[0].direction), 20.0, 1e-9);
  EXPECT_TRUE(ready[0].pose.moving);
  EXPECT_TRUE(ready[0].pose.centre_m.isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
  EXPECT_EQ(stamper.dropped(), 0);
  EXPECT_EQ(stamper.pending(), 0U);
}

TEST(LivePoseStamper, DropsWhatNoPoseCanCover) {
  const doa::ArrayGeometry geometry = level_pair();
  LivePoseStamper stamper(geometry, 1.0);
  std::vector<doa::DoaMeasurement> ready;
  stamper.add_pose(heading(10.0, 0.0));
  stamper.add_pose(heading(10.5, 0.0));
  // Older than the first pose: it will never be covered.
  std::vector<doa::DoaMeasurement> doas{doa_at(9.0, geometry)};
  stamper.add_doas(doas);
  stamper.release(10.6, ready);
  EXPECT_EQ(stamper.dropped(), 1);
  // The stream stops: a DOA after the newest pose waits max_gap + margin, then goes.
  doas = {doa_at(10.7, geometry)};
  stamper.add_doas(doas);
  stamper.release(11.0, ready);
  EXPECT_EQ(stamper.pending(), 1U);
  stamper.release(10.7 + 1.0 + LivePoseStamper::kWaitMargin_s + 0.01, ready);
  EXPECT_EQ(stamper.pending(), 0U);
  EXPECT_EQ(stamper.dropped(), 2);
  // Across a gap longer than max_gap_s, and across a 60 deg turn between samples.
  stamper.add_pose(heading(12.0, 0.0));
  stamper.add_pose(heading(12.1, 60.0));
  doas = {doa_at(11.0, geometry), doa_at(12.05, geometry)};
  stamper.add_doas(doas);
  stamper.release(12.2, ready);
  EXPECT_EQ(stamper.dropped(), 4);
  EXPECT_TRUE(ready.empty());
  // Bad samples are refused, not fatal.
  EXPECT_FALSE(stamper.add_pose(heading(std::numeric_limits<double>::quiet_NaN(), 0.0)));
  EXPECT_FALSE(stamper.add_pose(heading(12.1, 0.0)));
  EXPECT_EQ(stamper.refused_poses(), 2);
}

TEST(LivePoseStamper, AFullQueueDropsItsOldest) {
  const doa::ArrayGeometry geometry = level_pair();
  LivePoseStamper stamper(geometry, 1.0);
  std::vector<doa::DoaMeasurement> doas;
  for (std::size_t i = 0; i < LivePoseStamper::kMaxPending + 3; ++i)
    doas.push_back(doa_at(1.0 + 0.001 * static_cast<double>(i), geometry));
  stamper.add_doas(doas);
  EXPECT_EQ(stamper.pending(), LivePoseStamper::kMaxPending);
  EXPECT_EQ(stamper.dropped(), 3);
  std::vector<doa::DoaMeasurement> ready;
  stamper.add_pose(heading(0.0, 0.0));
  stamper.add_pose(heading(0.9, 0.0));
  stamper.add_pose(heading(1.8, 0.0));
  stamper.release(2.0, ready);
  ASSERT_EQ(ready.size(), LivePoseStamper::kMaxPending);
  EXPECT_NEAR(ready.front().time_s, 1.003, 1e-12);  // the first three went
}

}  // namespace
}  // namespace dronetrack::apps
