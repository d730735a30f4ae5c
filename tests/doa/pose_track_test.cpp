// Arrays that move (issue 15): pose interpolation at and between lines, slerp across the
// heading's +-180 deg wrap, the frame rotation of known vectors by known yaw/pitch/roll (hand
// computed), refusal outside the span, the live ring, and a DOA turned to the attitude at its
// time (direction, covariance, mirror image).
#include "doa/pose_track.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "doa/ls_doa_solver.hpp"
#include "doa/node_pipeline.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa {
namespace {

PoseSample pose(double time_s, Eigen::Vector3d position_m, double yaw_deg, double pitch_deg = 0.0,
                double roll_deg = 0.0) {
  return {time_s, position_m, yaw_deg, pitch_deg, roll_deg};
}

// Angle of the rotation between two attitudes, degrees.
double attitude_error_deg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b) * 180.0 / std::numbers::pi;
}

// An array whose mic centroid is off its origin, so centre_m shows the attitude too.
ArrayGeometry offset_pair() {
  // centroid (2, 0, 0)
  return ArrayGeometry{.id = std::string(1, 'P'), .mics_m = {{1.0, 0.0, 0.0}, {3.0, 0.0, 0.0}}};
}

TEST(ArrayAttitude, RotatesKnownVectorsByYawPitchRoll) {
  // Yaw 90: array +x is site +y.
  EXPECT_TRUE(attitude_to_site(90, 0, 0).col(0).isApprox(Eigen::Vector3d(0, 1, 0), 1e-12));
  // Pitch 30 about +y turns +x to (cos 30, 0, -sin 30); then yaw 90 to (0, cos 30, -sin 30).
  EXPECT_TRUE((attitude_to_site(90, 30, 0) * Eigen::Vector3d::UnitX())
                  .isApprox(Eigen::Vector3d(0, std::sqrt(3.0) / 2.0, -0.5), 1e-12));
  // Roll 90 about +x turns +y to +z.
  EXPECT_TRUE((attitude_to_site(0, 0, 90) * Eigen::Vector3d::UnitY())
                  .isApprox(Eigen::Vector3d(0, 0, 1), 1e-12));
  // All three on +y: roll 60 -> (0, 1/2, sqrt3/2); pitch 30 -> (sqrt3/4, 1/2, 3/4);
  // yaw 90 -> (-1/2, sqrt3/4, 3/4).
  EXPECT_TRUE((attitude_to_site(90, 30, 60) * Eigen::Vector3d::UnitY())
                  .isApprox(Eigen::Vector3d(-0.5, std::sqrt(3.0) / 4.0, 0.75), 1e-12));
  ArrayGeometry geometry = offset_pair();
  geometry.position_m = {10, 20, 2};
  geometry.yaw_deg = 90;
  geometry.pitch_deg = 30;
  geometry.roll_deg = 60;
  // Mic 0 at array (1, 0, 0): site (10, 20, 2) + (0, cos 30, -sin 30).
  EXPECT_TRUE(
      geometry.mic_site_m(0).isApprox(Eigen::Vector3d(10, 20 + std::sqrt(3.0) / 2.0, 1.5), 1e-12));
  const PoseStamp fixed = fixed_stamp(geometry);
  EXPECT_FALSE(fixed.moving);
  EXPECT_TRUE(fixed.centre_m.isApprox(geometry.centre_site_m(), 1e-12));
  EXPECT_TRUE(fixed.array_to_site.toRotationMatrix().isApprox(geometry.array_to_site(), 1e-12));
}

// Every user of array_to_site(): the LS solver's site-frame answer from a tilted array's
// physical TDOAs (mic site positions) is the true direction.
TEST(ArrayAttitude, SolverOfTiltedArrayReturnsSiteDirection) {
  ArrayGeometry geometry = testing::tetrahedron(-150.0);
  geometry.pitch_deg = 12.0;
  geometry.roll_deg = -25.0;
  const LsDoaSolver solver(geometry, LsDoaSettings{});
  for (const auto& [azimuth, elevation] : {std::pair{10.0, 20.0}, {170.0, 50.0}, {-95.0, 5.0}}) {
    const Eigen::Vector3d truth = direction_from_azel_deg(azimuth, elevation);
    const std::vector<double> arrival = testing::plane_wave_delays(geometry, truth, 343.0);
    std::vector<PairTdoa> tdoas;
    for (int p = 0; p < solver.pair_count(); ++p)
      tdoas.push_back({arrival[static_cast<std::size_t>(solver.pair_mic_i(p))] -
                           arrival[static_cast<std::size_t>(solver.pair_mic_j(p))],
                       1e-12, 0.9});
    const DoaSolution solution = solver.solve(tdoas);
    ASSERT_TRUE(solution.accepted);
    EXPECT_LT(angle_between_deg(solution.direction_site, truth), 1e-6) << azimuth;
  }
}

TEST(PoseTrack, AtEachLineIsThatLine) {
  const ArrayGeometry geometry = offset_pair();
  const PoseTrack track(
      {pose(0.0, {0, 0, 1}, 0), pose(1.0, {10, 0, 1}, 90, 10, -5), pose(2.5, {10, 15, 2}, 120)});
  for (const PoseSample& line : track.samples()) {
    const auto stamp = track.stamp(line.time_s, geometry);
    ASSERT_TRUE(stamp);
    EXPECT_TRUE(stamp->moving);
    const Eigen::Matrix3d rotation = attitude_to_site(line.yaw_deg, line.pitch_deg, line.roll_deg);
    EXPECT_LT(attitude_error_deg(stamp->array_to_site, Eigen::Quaterniond(rotation)), 1e-9);
    EXPECT_TRUE(
        stamp->centre_m.isApprox(line.position_m + rotation * Eigen::Vector3d(2, 0, 0), 1e-12))
        << line.time_s;
  }
}

TEST(PoseTrack, BetweenLinesPositionIsLinearAndHeadingTurnsEvenly) {
  const ArrayGeometry geometry = offset_pair();
  const PoseTrack track({pose(0.0, {0, 0, 1}, 10), pose(2.0, {8, -4, 3}, 40)});
  const auto quarter = track.stamp(0.5, geometry);
  ASSERT_TRUE(quarter);
  // A quarter of the way: origin (2, -1, 1.5), heading 17.5 deg, centroid 2 m along it.
  const double heading = 17.5 * std::numbers::pi / 180.0;
  EXPECT_TRUE(quarter->centre_m.isApprox(
      Eigen::Vector3d(2 + 2 * std::cos(heading), -1 + 2 * std::sin(heading), 1.5), 1e-12));
  EXPECT_LT(
      attitude_error_deg(quarter->array_to_site, Eigen::Quaterniond(attitude_to_site(17.5, 0, 0))),
      1e-9);
}

TEST(PoseTrack, HeadingAcrossTheWrapTurnsTheShortWay) {
  const ArrayGeometry geometry = offset_pair();
  // 170 -> -170 is a 20 deg turn through 180, not 340 deg back through 0.
  const PoseTrack track({pose(0.0, {0, 0, 0}, 170), pose(1.0, {0, 0, 0}, -170)});
  for (const auto& [time, expected_yaw] : {std::pair{0.5, 180.0}, {0.25, 175.0}, {0.75, -175.0}}) {
    const auto stamp = track.stamp(time, geometry);
    ASSERT_TRUE(stamp);
    EXPECT_LT(attitude_error_deg(stamp->array_to_site,
                                 Eigen::Quaterniond(attitude_to_site(expected_yaw, 0, 0))),
              1e-9)
        << time;
  }
  // Half way the array's +x points at site -x.
  EXPECT_TRUE((track.stamp(0.5, geometry)->array_to_site * Eigen::Vector3d::UnitX())
                  .isApprox(Eigen::Vector3d(-1, 0, 0), 1e-12));
}

TEST(PoseTrack, VelocityIsThatOfTheIntervalAroundTheTime) {
  const PoseTrack track(
      {pose(0.0, {0, 0, 1}, 0), pose(0.5, {1, 0, 1}, 0), pose(1.5, {1, 3, 0}, 0)});
  EXPECT_TRUE(track.velocity_mps(0.2)->isApprox(Eigen::Vector3d(2, 0, 0), 1e-12));
  EXPECT_TRUE(track.velocity_mps(1.0)->isApprox(Eigen::Vector3d(0, 3, -1), 1e-12));
  EXPECT_TRUE(track.velocity_mps(1.5)->isApprox(Eigen::Vector3d(0, 3, -1), 1e-12));
  EXPECT_FALSE(track.velocity_mps(1.6));
}

TEST(PoseTrack, RefusesTimesOutsideItsSpan) {
  const ArrayGeometry geometry = offset_pair();
  const PoseTrack track({pose(5.0, {0, 0, 0}, 0), pose(6.0, {1, 0, 0}, 0)});
  EXPECT_FALSE(track.stamp(4.999, geometry));
  EXPECT_FALSE(track.stamp(6.001, geometry));
  EXPECT_FALSE(track.stamp(std::nan(""), geometry));
  EXPECT_TRUE(track.stamp(5.0, geometry));
  EXPECT_TRUE(track.stamp(6.0, geometry));
  EXPECT_THROW(PoseTrack({pose(0.0, {0, 0, 0}, 0)}), std::invalid_argument);
  EXPECT_THROW(PoseTrack({pose(1.0, {0, 0, 0}, 0), pose(1.0, {0, 0, 0}, 0)}),
               std::invalid_argument);
}

TEST(PoseRing, StampsBetweenArrivedSamplesOnly) {
  PoseRing ring(0.5);
  const Eigen::Vector3d centroid(2, 0, 0);
  EXPECT_FALSE(ring.stamp(0.0, centroid));
  EXPECT_TRUE(ring.push(pose(0.0, {0, 0, 0}, 0)));
  EXPECT_TRUE(ring.push(pose(0.1, {1, 0, 0}, 0)));
  EXPECT_FALSE(ring.push(pose(0.1, {1, 0, 0}, 0)));             // repeated time
  EXPECT_FALSE(ring.push(pose(0.2, {std::nan(""), 0, 0}, 0)));  // non-finite
  EXPECT_EQ(ring.refused(), 2);
  const auto middle = ring.stamp(0.05, centroid);
  ASSERT_TRUE(middle);
  EXPECT_TRUE(middle->centre_m.isApprox(Eigen::Vector3d(2.5, 0, 0), 1e-12));
  EXPECT_FALSE(ring.stamp(0.15, centroid));  // not yet arrived
  EXPECT_TRUE(ring.push(pose(1.0, {2, 0, 0}, 0)));
  EXPECT_FALSE(ring.stamp(0.5, centroid));  // across a 0.9 s gap
  EXPECT_TRUE(ring.push(pose(1.1, {3, 0, 0}, 60)));
  EXPECT_FALSE(ring.stamp(1.05, centroid));  // a 60 deg turn between lines
  // Past its capacity the oldest go: still stamps the newest, no longer the first.
  for (std::size_t i = 0; i < PoseRing::kCapacity; ++i)
    ASSERT_TRUE(ring.push(pose(2.0 + 0.01 * static_cast<double>(i), {0, 0, 0}, 60)));
  EXPECT_EQ(ring.size(), PoseRing::kCapacity);
  EXPECT_FALSE(ring.stamp(0.05, centroid));
  EXPECT_TRUE(ring.stamp(ring.newest_s() - 0.005, centroid));
}

TEST(Restamp, TurnsDirectionAndCovarianceToTheAttitudeAtTheFrame) {
  DoaMeasurement measurement;
  measurement.direction = Eigen::Vector3d::UnitX();
  measurement.azel_covariance_rad2 << 1e-4, 0.0, 0.0, 4e-4;
  // Solved with the config's level array; at this frame the array was rolled 90 deg, so the
  // array's horizontal (the azimuth direction, +y) is now vertical: the variances swap.
  PoseStamp stamp;
  stamp.array_to_site = Eigen::Quaterniond(attitude_to_site(0, 0, 90));
  stamp.moving = true;
  restamp(measurement, stamp, Eigen::Matrix3d::Identity());
  EXPECT_TRUE(measurement.direction.isApprox(Eigen::Vector3d::UnitX(), 1e-12));
  EXPECT_NEAR(measurement.azel_covariance_rad2(0, 0), 4e-4, 1e-12);
  EXPECT_NEAR(measurement.azel_covariance_rad2(1, 1), 1e-4, 1e-12);
  EXPECT_NEAR(measurement.azel_covariance_rad2(0, 1), 0.0, 1e-12);
  EXPECT_TRUE(measurement.pose.moving);

  // Solved with a yaw of 30 (direction at azimuth 50 in that frame); the array had turned to
  // yaw 100: the direction is at azimuth 120, elevation unchanged, variances unchanged.
  DoaMeasurement turned;
  turned.direction = direction_from_azel_deg(50, 20);
  turned.azel_covariance_rad2 << 2e-4, 1e-5, 1e-5, 3e-4;
  stamp.array_to_site = Eigen::Quaterniond(attitude_to_site(100, 0, 0));
  restamp(turned, stamp, attitude_to_site(30, 0, 0));
  EXPECT_NEAR(azimuth_deg(turned.direction), 120.0, 1e-9);
  EXPECT_NEAR(elevation_deg(turned.direction), 20.0, 1e-9);
  EXPECT_TRUE(turned.azel_covariance_rad2.isApprox(
      (Eigen::Matrix2d() << 2e-4, 1e-5, 1e-5, 3e-4).finished(), 1e-9));
}

TEST(Restamp, MirrorPairKeepsTheImageAboveTheArrayPlane) {
  // A planar array turned upside down (roll 180): its normal points down, so the image above
  // the plane is the mirror of the turned direction, i.e. the original one.
  DoaMeasurement measurement;
  measurement.ambiguity = DoaAmbiguity::mirror_up_down;
  measurement.direction = direction_from_azel_deg(0, 30);
  measurement.ambiguity_axis = Eigen::Vector3d::UnitZ();
  PoseStamp stamp;
  stamp.array_to_site = Eigen::Quaterniond(attitude_to_site(0, 0, 180));
  restamp(measurement, stamp, Eigen::Matrix3d::Identity());
  EXPECT_TRUE(measurement.ambiguity_axis.isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE(measurement.direction.isApprox(direction_from_azel_deg(0, 30), 1e-12));
  // A cone's axis follows the array (yaw 90: mic axis +x becomes +y).
  DoaMeasurement cone;
  cone.ambiguity = DoaAmbiguity::cone;
  cone.ambiguity_axis = Eigen::Vector3d::UnitX();
  cone.cone_angle_rad = 0.7;
  cone.direction = {std::cos(0.7), std::sin(0.7), 0.0};  // the cone's horizontal point
  stamp.array_to_site = Eigen::Quaterniond(attitude_to_site(90, 0, 0));
  restamp(cone, stamp, Eigen::Matrix3d::Identity());
  EXPECT_TRUE(cone.ambiguity_axis.isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_TRUE(cone.direction.isApprox(Eigen::Vector3d(-std::sin(0.7), std::cos(0.7), 0), 1e-12));
  EXPECT_DOUBLE_EQ(cone.cone_angle_rad, 0.7);
}

TEST(Restamp, ConeKeepsItsHorizontalDisplayPoint) {
  // A two-mic array along +x rolled 40 deg about its own axis: the axis stays +x, the point
  // solved in the level frame would tilt by 40 deg; the cone's horizontal point is reported.
  DoaMeasurement cone;
  cone.ambiguity = DoaAmbiguity::cone;
  cone.ambiguity_axis = Eigen::Vector3d::UnitX();
  cone.cone_angle_rad = 0.7;
  cone.direction = {std::cos(0.7), std::sin(0.7), 0.0};
  cone.azel_covariance_rad2 << 1e-4, 0.0, 0.0, 2.4;  // the free angle around the axis: vertical
  PoseStamp stamp;
  stamp.array_to_site = Eigen::Quaterniond(attitude_to_site(0, 0, 40));
  restamp(cone, stamp, Eigen::Matrix3d::Identity());
  EXPECT_TRUE(cone.ambiguity_axis.isApprox(Eigen::Vector3d::UnitX(), 1e-12));
  EXPECT_TRUE(cone.direction.isApprox(Eigen::Vector3d(std::cos(0.7), std::sin(0.7), 0), 1e-12));
  EXPECT_NEAR(cone.azel_covariance_rad2(0, 0), 1e-4, 1e-12);
  EXPECT_NEAR(cone.azel_covariance_rad2(1, 1), 2.4, 1e-9);
  // Tilted 30 deg in pitch, the axis leaves the horizontal; the point is on the cone, level.
  stamp.array_to_site = Eigen::Quaterniond(attitude_to_site(20, 30, 0));
  restamp(cone, stamp, Eigen::Matrix3d::Identity());
  const Eigen::Vector3d axis = attitude_to_site(20, 30, 0).col(0);
  EXPECT_TRUE(cone.ambiguity_axis.isApprox(axis, 1e-12));
  EXPECT_NEAR(std::acos(cone.direction.dot(axis)), 0.7, 1e-12);
  EXPECT_NEAR(cone.direction.z(), std::cos(0.7) * axis.z(), 1e-12);  // along the axis only
  EXPECT_NEAR(cone.direction.norm(), 1.0, 1e-12);
}

constexpr double kRate = 48000.0;

// A plane wave from `direction_site` at `geometry`, in light sensor noise.
testing::Recording plane_wave(const ArrayGeometry& geometry, const Eigen::Vector3d& direction_site,
                              double seconds) {
  const auto frames = static_cast<std::size_t>(seconds * kRate);
  testing::Recording recording = testing::silent_recording(4, frames);
  const testing::BandNoise source(static_cast<int>(frames), kRate, 1000.0, 4000.0, 5);
  testing::add_source(recording, geometry, direction_site, source, 0.05);
  testing::add_sensor_noise(recording, kRate, 200.0, 8000.0, 0.01, 77);
  return recording;
}

std::vector<DoaMeasurement> run(NodePipeline& pipeline, const testing::Recording& recording) {
  std::vector<DoaMeasurement> out;
  constexpr std::size_t kBlock = 1024;
  for (std::size_t first = 0; first < recording.frames(); first += kBlock)
    pipeline.process(recording.view(first, std::min(kBlock, recording.frames() - first)), out);
  return out;
}

// Each DOA from its own frame's audio only.
void use_per_frame(DoaParams& params) {
  params.tdoa_tracker = TdoaTracker::per_frame;
  params.ground_echo = false;
}

// A pose file that holds still at a pose other than the config's gives the DOAs a config with
// that fixed pose gives: same directions, covariances and acoustic centre.
TEST(NodePipelinePose, ConstantPoseEqualsTheSameFixedPose) {
  ArrayGeometry actual = testing::tetrahedron(70.0);
  actual.position_m = {30.0, -12.0, 2.0};
  actual.pitch_deg = 8.0;
  actual.roll_deg = -5.0;
  const Eigen::Vector3d truth = direction_from_azel_deg(-120.0, 30.0);
  const testing::Recording recording = plane_wave(actual, truth, 2.0);
  DoaParams params;
  use_per_frame(params);

  NodePipeline fixed(actual, 0, params, kRate, 343.0);
  const std::vector<DoaMeasurement> expected = run(fixed, recording);

  const ArrayGeometry nominal = testing::tetrahedron(0.0);  // the config: level, at the origin
  NodePipeline moving(nominal, 0, params, kRate, 343.0);
  moving.set_pose_track(PoseTrack({pose(0.0, actual.position_m, 70.0, 8.0, -5.0),
                                   pose(1.0, actual.position_m, 70.0, 8.0, -5.0),
                                   pose(2.0, actual.position_m, 70.0, 8.0, -5.0)}));
  const std::vector<DoaMeasurement> got = run(moving, recording);

  ASSERT_GE(expected.size(), 5U);
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_DOUBLE_EQ(got[i].time_s, expected[i].time_s);
    EXPECT_LT(angle_between_deg(got[i].direction, expected[i].direction), 1e-6);
    EXPECT_LT(angle_between_deg(got[i].direction, truth), 1.0);
    EXPECT_TRUE(got[i].azel_covariance_rad2.isApprox(expected[i].azel_covariance_rad2, 1e-6));
    EXPECT_TRUE(got[i].pose.moving);
    EXPECT_FALSE(expected[i].pose.moving);
    EXPECT_TRUE(got[i].pose.centre_m.isApprox(expected[i].pose.centre_m, 1e-12));
    EXPECT_TRUE(got[i].pose.centre_m.isApprox(actual.centre_site_m(), 1e-12));
  }
}

// A platform turning at 20 deg/s carries a source fixed in its own frame (on its deck): each
// DOA is that array-frame direction turned by the heading at the DOA's own time, not at the
// config's yaw or any other frame's. Frames outside the pose's span are dropped and counted.
TEST(NodePipelinePose, DirectionFollowsTheHeadingAtEachFramesTime) {
  const ArrayGeometry nominal = testing::tetrahedron(0.0);
  const Eigen::Vector3d in_array_frame = direction_from_azel_deg(30.0, 20.0);
  const testing::Recording recording = plane_wave(nominal, in_array_frame, 3.0);
  std::vector<PoseSample> lines;
  for (int i = 0; i <= 25; ++i)  // 0 .. 2.5 s at 10 Hz: the recording's last frames are outside
    lines.push_back(pose(0.1 * i, {0.1 * i, 0.0, 1.5}, -170.0 + 2.0 * i));
  DoaParams params;
  use_per_frame(params);
  NodePipeline pipeline(nominal, 0, params, kRate, 343.0);
  pipeline.set_pose_track(PoseTrack(lines));
  const std::vector<DoaMeasurement> doas = run(pipeline, recording);
  ASSERT_GE(doas.size(), 10U);
  for (const DoaMeasurement& doa : doas) {
    ASSERT_LE(doa.time_s, 2.5);
    const double heading_deg = -170.0 + 20.0 * doa.time_s;
    const Eigen::Vector3d expected = attitude_to_site(heading_deg, 0, 0) * in_array_frame;
    EXPECT_LT(angle_between_deg(doa.direction, expected), 1.0) << doa.time_s;
    EXPECT_NEAR(doa.pose.centre_m.x(), doa.time_s + nominal.centre_site_m().x(), 1e-9);
  }
  // One frame's error would be ~0.1 deg; a 20 deg/s turn moves 4.8 deg per hop: a DOA turned by
  // the wrong frame's heading would be off by that much.
  EXPECT_GT(pipeline.diagnostics().unposed_doas, 0);
  EXPECT_EQ(pipeline.diagnostics().doas_published, static_cast<std::int64_t>(doas.size()));
}

}  // namespace
}  // namespace dronetrack::doa
