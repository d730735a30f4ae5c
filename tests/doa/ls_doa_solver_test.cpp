// Least-squares DOA from exact TDOAs: exact directions all over the sphere, yawed arrays,
// degenerate geometries and their documented ambiguity, covariance propagation.
#include "doa/ls_doa_solver.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa::ls_doa_solver_test {
namespace {

using testing::tetrahedron;

std::vector<PairTdoa> exact_tdoas(const LsDoaSolver& solver, const ArrayGeometry& geometry,
                                  const Eigen::Vector3d& direction_site, double std_s = 1e-6) {
  const Eigen::Vector3d direction_array = geometry.array_to_site().transpose() * direction_site;
  std::vector<PairTdoa> tdoas;
  for (int p = 0; p < solver.pair_count(); ++p)
    tdoas.push_back({solver.tdoa_for_direction(p, direction_array), std_s * std_s, 0.9});
  return tdoas;
}

struct SphereCase {
  double azimuth_deg;
  double elevation_deg;
  double yaw_deg;
};

class ExactDirection : public ::testing::TestWithParam<SphereCase> {};

TEST_P(ExactDirection, RecoversDirectionFromExactTdoas) {
  const SphereCase sphere = GetParam();
  const ArrayGeometry geometry = tetrahedron(sphere.yaw_deg);
  const LsDoaSolver solver(geometry, LsDoaSettings{});
  const Eigen::Vector3d truth = direction_from_azel_deg(sphere.azimuth_deg, sphere.elevation_deg);
  // Check the TDOAs are the ones the physics gives: t_i - t_j with t_i = -u^T p_i / c.
  const std::vector<double> arrival = testing::plane_wave_delays(geometry, truth, 343.0);
  const std::vector<PairTdoa> tdoas = exact_tdoas(solver, geometry, truth);
  for (int p = 0; p < solver.pair_count(); ++p) {
    const double physics = arrival[static_cast<std::size_t>(solver.pair_mic_i(p))] -
                           arrival[static_cast<std::size_t>(solver.pair_mic_j(p))];
    ASSERT_NEAR(tdoas[static_cast<std::size_t>(p)].tdoa_s, physics, 1e-12);
  }
  const DoaSolution solution = solver.solve(tdoas);
  ASSERT_TRUE(solution.accepted);
  EXPECT_EQ(solution.ambiguity, DoaAmbiguity::none);
  EXPECT_LT(angle_between_deg(solution.direction_site, truth), 1e-6);
  EXPECT_NEAR(solution.norm, 1.0, 1e-9);
  EXPECT_NEAR(wrap_deg_180(azimuth_deg(solution.direction_site) - sphere.azimuth_deg), 0.0,
              std::abs(sphere.elevation_deg) > 89.0 ? 180.0 : 1e-6);
}

std::vector<SphereCase> sphere_cases() {
  std::vector<SphereCase> cases;
  for (const double yaw : {0.0, 45.0, -135.0, 180.0})
    for (const double elevation : {-80.0, -30.0, 0.0, 20.0, 60.0, 89.5})
      for (const double azimuth : {-180.0, -179.9, -120.0, -45.0, 0.0, 30.0, 90.0, 150.0, 179.9})
        cases.push_back({azimuth, elevation, yaw});
  return cases;
}
INSTANTIATE_TEST_SUITE_P(Sphere, ExactDirection, ::testing::ValuesIn(sphere_cases()));

TEST(LsDoaSolver, AzimuthWrapsAtPlusMinus180) {
  const ArrayGeometry geometry = tetrahedron(30.0);
  const LsDoaSolver solver(geometry, LsDoaSettings{});
  for (const double azimuth : {179.999, -179.999, 180.0}) {
    const Eigen::Vector3d truth = direction_from_azel_deg(azimuth, 10.0);
    const DoaSolution solution = solver.solve(exact_tdoas(solver, geometry, truth));
    ASSERT_TRUE(solution.accepted);
    EXPECT_NEAR(wrap_deg_180(azimuth_deg(solution.direction_site) - azimuth), 0.0, 1e-6);
    EXPECT_NEAR(std::abs(azimuth_deg(solution.direction_site)), 180.0, 0.01);
  }
}

TEST(LsDoaSolver, PlanarArrayReportsUpperMirror) {
  ArrayGeometry geometry;
  geometry.id = "square";
  geometry.yaw_deg = 20.0;
  geometry.mics_m = {{0.3, 0.3, 0}, {-0.3, 0.3, 0}, {-0.3, -0.3, 0}, {0.3, -0.3, 0}};
  const LsDoaSolver solver(geometry, LsDoaSettings{});
  EXPECT_EQ(solver.rank(), 2);
  for (const double elevation : {35.0, -35.0}) {
    const Eigen::Vector3d truth = direction_from_azel_deg(-100.0, elevation);
    const DoaSolution solution = solver.solve(exact_tdoas(solver, geometry, truth));
    ASSERT_TRUE(solution.accepted);
    EXPECT_EQ(solution.ambiguity, DoaAmbiguity::mirror_up_down);
    const Eigen::Vector3d upper = direction_from_azel_deg(-100.0, std::abs(elevation));
    EXPECT_LT(angle_between_deg(solution.direction_site, upper), 1e-5);
  }
}

TEST(LsDoaSolver, TwoMicsReportTheCone) {
  ArrayGeometry geometry;
  geometry.id = "pair";
  geometry.yaw_deg = 90.0;  // mic axis along site +y
  geometry.mics_m = {{0.3, 0, 0}, {-0.3, 0, 0}};
  const LsDoaSolver solver(geometry, LsDoaSettings{});
  EXPECT_EQ(solver.rank(), 1);
  const Eigen::Vector3d truth = direction_from_azel_deg(50.0, 25.0);
  const DoaSolution solution = solver.solve(exact_tdoas(solver, geometry, truth));
  ASSERT_TRUE(solution.accepted);
  EXPECT_EQ(solution.ambiguity, DoaAmbiguity::cone);
  // Only the angle to the axis is known: it must match; the reported vector is on the cone.
  const Eigen::Vector3d axis = Eigen::Vector3d::UnitY();
  EXPECT_NEAR(solution.direction_site.dot(axis), truth.dot(axis), 1e-9);
  EXPECT_NEAR(solution.direction_site.z(), 0.0, 1e-9);  // documented: the horizontal one
  // The unresolved angle carries a huge variance, never a confident made-up direction.
  EXPECT_GT(solution.azel_covariance_rad2.trace(), 1.0);
}

TEST(LsDoaSolver, RejectsInconsistentTdoasAndDropsOneOutlier) {
  const ArrayGeometry geometry = tetrahedron();
  const LsDoaSolver solver(geometry, LsDoaSettings{});
  const Eigen::Vector3d truth = direction_from_azel_deg(60.0, 20.0);
  std::vector<PairTdoa> tdoas = exact_tdoas(solver, geometry, truth, 2e-6);
  tdoas[2].tdoa_s += 400e-6;  // one pair locked on a reflection
  const DoaSolution solution = solver.solve(tdoas);
  ASSERT_TRUE(solution.accepted);
  EXPECT_EQ(solution.dropped_pair, 2);
  EXPECT_LT(angle_between_deg(solution.direction_site, truth), 1e-3);
  // All TDOAs maximal at once is no plane wave.
  for (auto& tdoa : tdoas) tdoa.tdoa_s = 2.4e-3;
  EXPECT_FALSE(solver.solve(tdoas).accepted);
}

TEST(LsDoaSolver, CovarianceMatchesScatterOfNoisyTdoas) {
  // NEES of the (az, el) error with the propagated covariance: mean ~2 for 2 dof when honest.
  const ArrayGeometry geometry = tetrahedron(-30.0);
  const LsDoaSolver solver(geometry, LsDoaSettings{});
  std::mt19937 random(7);
  const double std_s = 4e-6;
  std::normal_distribution<double> noise(0.0, std_s);
  double nees_sum = 0.0;
  int count = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Vector3d truth =
        direction_from_azel_deg(-170.0 + 0.17 * trial, -20.0 + 0.03 * trial);
    std::vector<PairTdoa> tdoas = exact_tdoas(solver, geometry, truth, std_s);
    for (auto& tdoa : tdoas) tdoa.tdoa_s += noise(random);
    const DoaSolution solution = solver.solve(tdoas);
    ASSERT_TRUE(solution.accepted);
    const Eigen::Vector2d error(
        wrap_rad_pi((azimuth_deg(solution.direction_site) - azimuth_deg(truth)) * M_PI / 180.0),
        (elevation_deg(solution.direction_site) - elevation_deg(truth)) * M_PI / 180.0);
    nees_sum += error.dot(solution.azel_covariance_rad2.inverse() * error);
    ++count;
  }
  const double mean_nees = nees_sum / count;
  EXPECT_GT(mean_nees, 1.4);
  EXPECT_LT(mean_nees, 2.6);
}

}  // namespace
}  // namespace dronetrack::doa::ls_doa_solver_test
