// Issue 16: two swapped channels of a regular tetrahedron are a mirror of the array; the fusion
// names them from tracks the other arrays fix (fusion/array_mirror_check.hpp).
#include "fusion/array_mirror_check.hpp"

#include <cmath>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/fusion_engine.hpp"
#include "scene.hpp"

namespace dronetrack::fusion::array_mirror_check_test {
namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;
constexpr double kSpeed = 343.0;

// The direction a node whose channels a and b are swapped reports for a source in `truth`
// (site frame): the truth reflected, in the array's frame, through the plane bisecting a and b.
Eigen::Vector3d swapped_doa(const doa::ArrayGeometry& array, int a, int b,
                            const Eigen::Vector3d& truth) {
  const Eigen::Matrix3d to_site = array.array_to_site();
  const Eigen::Vector3d normal = (array.mics_m[a] - array.mics_m[b]).normalized();
  const Eigen::Vector3d local = to_site.transpose() * truth;
  return to_site * (local - 2.0 * local.dot(normal) * normal);
}

Eigen::Vector3d jitter(const Eigen::Vector3d& direction, double std_deg, std::mt19937_64& random) {
  std::normal_distribution<double> normal(0.0, std_deg * kRadPerDeg);
  return (direction + Eigen::Vector3d(normal(random), normal(random), normal(random))).normalized();
}

// A source circling the array at 20 deg/s with its elevation swinging 5-65 deg: DOAs every
// 0.05 s for duration_s. `report` turns the true direction (site frame) into the DOA the node
// reports; the reference (the track) carries 0.3 deg of error, the DOA 0.3 deg more.
template <typename Report>
MirrorCheckStatus run(ArrayMirrorCheck& check, const doa::ArrayGeometry& array, double duration_s,
                      Report report, std::vector<MirrorSwapEvent>& events, unsigned seed = 1) {
  std::mt19937_64 random(seed);
  for (double t = 0.0; t < duration_s; t += 0.05) {
    const double azimuth_deg = 20.0 * t;
    const double elevation_deg = 35.0 + 30.0 * std::sin(0.21 * t);
    const Eigen::Vector3d truth = doa::direction_from_azel_deg(azimuth_deg, elevation_deg);
    const Eigen::Vector3d reference = jitter(truth, 0.3, random);
    const Eigen::Vector3d measured = jitter(report(truth), 0.3, random);
    check.observe(t, measured, array.array_to_site(), {&reference, 1});
    for (const MirrorSwapEvent& event : check.events()) events.push_back(event);
    check.clear_events();
  }
  return check.status();
}

doa::ArrayGeometry turned_tetrahedron() {
  doa::ArrayGeometry array = testing::tetrahedron("A1", {0, 0, 1.5});
  array.yaw_deg = 30.0;  // the mirrors are the array's, not the site's
  return array;
}

TEST(ArrayMirrorCheck, EverySwapOfARegularTetrahedronIsAMirror) {
  const ArrayMirrorCheck check(0, turned_tetrahedron(), {});
  EXPECT_EQ(check.mirrors(), 6);
  // Moved 2 cm along x, the top mic leaves the plane bisecting mics 1 and 2: that swap is no
  // mirror any more (the node's own swap check sees it).
  doa::ArrayGeometry moved = turned_tetrahedron();
  moved.mics_m[0].x() += 0.02;
  const ArrayMirrorCheck irregular(0, moved, {});
  EXPECT_LT(irregular.mirrors(), 6);
  EXPECT_FALSE(irregular.is_mirror(1, 2));
}

TEST(ArrayMirrorCheck, NamesEachSwap) {
  const doa::ArrayGeometry array = turned_tetrahedron();
  for (const auto& [a, b] : std::vector<std::pair<int, int>>{{0, 1}, {0, 3}, {1, 2}, {2, 3}}) {
    const int first = a;
    const int second = b;
    ArrayMirrorCheck check(0, array, {});
    std::vector<MirrorSwapEvent> events;
    const MirrorCheckStatus status = run(
        check, array, 60.0,
        [&array, first, second](const Eigen::Vector3d& truth) {
          return swapped_doa(array, first, second, truth);
        },
        events);
    ASSERT_EQ(events.size(), 1U) << "swap " << a << "-" << b;
    EXPECT_EQ(events[0].channel_a, a);
    EXPECT_EQ(events[0].channel_b, b);
    EXPECT_GE(events[0].sectors, 4);
    EXPECT_LT(events[0].swapped_misfit_deg, 1.0);
    EXPECT_GT(events[0].wired_misfit_deg, 20.0);
    EXPECT_EQ(status.swapped_a, a);
    EXPECT_EQ(status.swapped_b, b);
  }
}

TEST(ArrayMirrorCheck, CleanAndYawErrorsAreSilent) {
  const doa::ArrayGeometry array = turned_tetrahedron();
  for (const double yaw_error_deg : {0.0, 3.0, 10.0}) {
    ArrayMirrorCheck check(0, array, {});
    std::vector<MirrorSwapEvent> events;
    const Eigen::Matrix3d yaw =
        Eigen::AngleAxisd(yaw_error_deg * kRadPerDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const MirrorCheckStatus status = run(
        check, array, 60.0, [&yaw](const Eigen::Vector3d& truth) { return yaw * truth; }, events,
        2);
    EXPECT_TRUE(events.empty()) << "yaw error " << yaw_error_deg << " deg";
    EXPECT_EQ(status.swapped_a, -1);
    // Judged (the directions spanned enough sectors) and far under the bar.
    EXPECT_GE(status.best_sectors, 4) << "yaw error " << yaw_error_deg << " deg";
    EXPECT_LT(status.largest_ratio, 1.0) << "yaw error " << yaw_error_deg << " deg";
  }
}

TEST(ArrayMirrorCheck, OneDirectionIsNotJudged) {
  const doa::ArrayGeometry array = turned_tetrahedron();
  ArrayMirrorCheck check(0, array, {});
  std::mt19937_64 random(3);
  const Eigen::Vector3d truth = doa::direction_from_azel_deg(40.0, 30.0);
  for (double t = 0.0; t < 60.0; t += 0.05) {
    const Eigen::Vector3d reference = jitter(truth, 0.3, random);
    const Eigen::Vector3d measured = jitter(swapped_doa(array, 1, 2, truth), 0.3, random);
    check.observe(t, measured, array.array_to_site(), {&reference, 1});
  }
  EXPECT_TRUE(check.events().empty());
  EXPECT_EQ(check.status().best_ratio, 0.0);
}

// The engine: three arrays, a drone circling above the middle one; A2's channels 1 and 2 are
// swapped, so its DOAs are mirrored. The tracks A1 and A3 fix name it; the same scene clean, or
// with A2's yaw 3 deg off, says nothing.
std::vector<MirrorSwapEvent> engine_run(int swapped_array, double yaw_error_deg) {
  std::vector<doa::ArrayGeometry> arrays = {testing::tetrahedron("A1", {-30, 0, 1.5}),
                                            testing::tetrahedron("A2", {0, 0, 1.5}),
                                            testing::tetrahedron("A3", {30, 5, 1.5})};
  arrays[1].yaw_deg = 30.0;
  FusionEngine engine(FusionParams{}, arrays, kSpeed);
  const testing::Trajectory path = [](double t) {
    return Eigen::Vector3d(15.0 * std::cos(0.4 * t), 15.0 * std::sin(0.4 * t),
                           20.0 + 10.0 * std::sin(0.13 * t));
  };
  std::mt19937_64 random(5);
  const testing::DoaNoise noise{0.3, true};
  const Eigen::Matrix3d yaw =
      Eigen::AngleAxisd(yaw_error_deg * kRadPerDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  std::vector<MirrorSwapEvent> events;
  for (double t = 1.0; t < 40.0; t += 0.05) {
    for (int a = 0; a < 3; ++a) {
      doa::DoaMeasurement m = testing::ideal_doa(path, arrays[a], a, t, kSpeed, noise, random);
      if (a == 1) m.direction = yaw * m.direction;
      if (a == swapped_array) m.direction = swapped_doa(arrays[a], 1, 2, m.direction);
      engine.add(m);
    }
    engine.advance_to(t);
  }
  engine.take_mirror_events(events);
  return events;
}

TEST(ArrayMirrorCheck, EngineNamesTheSwappedArray) {
  const std::vector<MirrorSwapEvent> events = engine_run(1, 0.0);
  ASSERT_EQ(events.size(), 1U);
  EXPECT_EQ(events[0].array, 1);
  EXPECT_EQ(events[0].channel_a, 1);
  EXPECT_EQ(events[0].channel_b, 2);
  EXPECT_TRUE(engine_run(-1, 0.0).empty());
  EXPECT_TRUE(engine_run(-1, 3.0).empty());
}

}  // namespace
}  // namespace dronetrack::fusion::array_mirror_check_test
