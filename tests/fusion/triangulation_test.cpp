#include "fusion/triangulation.hpp"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "fusion/measurement_model.hpp"

namespace dronetrack::fusion::triangulation_test {
namespace {

Ray ray_to(const Eigen::Vector3d& origin, const Eigen::Vector3d& target, double std_rad) {
  return {origin, (target - origin).normalized(),
          MeasurementCovariance::Identity() * std_rad * std_rad};
}

TEST(Triangulation, ExactOnNoiselessRays) {
  const Eigen::Vector3d target(37.0, -12.0, 25.0);
  const std::vector<Eigen::Vector3d> origins{
      {0, 0, 1.5}, {20, 0, 1.5}, {-50, 80, 3.0}, {100, 100, 2.0}};
  for (std::size_t count = 2; count <= origins.size(); ++count) {
    std::vector<Ray> rays;
    for (std::size_t k = 0; k < count; ++k) rays.push_back(ray_to(origins[k], target, 0.01));
    const auto fix = triangulate_least_squares(rays);
    ASSERT_TRUE(fix.has_value());
    EXPECT_LT((fix->position_m - target).norm(), 1e-6) << count << " rays";
    EXPECT_TRUE(fix->in_front);
    EXPECT_LT(fix->chi_square, 1e-9);
  }
  const auto seed = triangulate_seed_xy(
      std::vector<Ray>{ray_to(origins[0], target, 0.01), ray_to(origins[1], target, 0.01)});
  ASSERT_TRUE(seed.has_value());
  EXPECT_LT((seed->position_m - target).norm(), 1e-6);
}

TEST(Triangulation, ParallelRaysAreRefused) {
  const std::vector<Ray> rays{{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d::UnitX(),
                               MeasurementCovariance::Identity() * 1e-4},
                              {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d::UnitX(),
                               MeasurementCovariance::Identity() * 1e-4}};
  EXPECT_FALSE(triangulate_least_squares(rays).has_value());
  EXPECT_FALSE(triangulate_least_squares(std::vector<Ray>{rays[0]}).has_value());
}

TEST(Triangulation, ConditioningWorsensNearTheArrayLine) {
  const Eigen::Vector3d a(0, 0, 1.5);
  const Eigen::Vector3d b(20, 0, 1.5);
  const auto broadside = triangulate_least_squares(
      std::vector<Ray>{ray_to(a, {10, 30, 10}, 0.01), ray_to(b, {10, 30, 10}, 0.01)});
  const auto along = triangulate_least_squares(
      std::vector<Ray>{ray_to(a, {60, 1, 3}, 0.01), ray_to(b, {60, 1, 3}, 0.01)});
  ASSERT_TRUE(broadside && along);
  EXPECT_GT(along->condition_number, 10.0 * broadside->condition_number);
  EXPECT_GT(along->covariance_m2.trace(), 10.0 * broadside->covariance_m2.trace());
}

// Monte Carlo NEES: with angle noise as declared, (p - truth)^T Cov^-1 (p - truth) averages 3.
TEST(Triangulation, CovarianceIsHonestOnNoisyRays) {
  const Eigen::Vector3d target(30.0, 45.0, 20.0);
  const std::vector<Eigen::Vector3d> origins{{0, 0, 1.5}, {20, 0, 1.5}, {-10, 60, 1.5}};
  std::mt19937_64 random(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double std_rad = 0.5 * M_PI / 180.0;
  constexpr int kTrials = 2000;
  for (std::size_t count : {2u, 3u}) {
    double nees_sum = 0.0;
    for (int trial = 0; trial < kTrials; ++trial) {
      std::vector<Ray> rays;
      for (std::size_t k = 0; k < count; ++k) {
        const Measurement azel = azel_of(target - origins[k]);
        const double az = azel(0) + std_rad * normal(random);
        const double el = azel(1) + std_rad * normal(random);
        rays.push_back({origins[k],
                        {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)},
                        MeasurementCovariance::Identity() * std_rad * std_rad});
      }
      const auto fix = triangulate_least_squares(rays);
      ASSERT_TRUE(fix.has_value());
      const Eigen::Vector3d error = fix->position_m - target;
      nees_sum += error.dot(fix->covariance_m2.inverse() * error);
    }
    const double mean_nees = nees_sum / kTrials;
    // chi-square(3 * 2000) / 2000: mean 3, std sqrt(6 / 2000) = 0.055; allow ~4 sigma plus the
    // small bias of the linearisation.
    EXPECT_NEAR(mean_nees, 3.0, 0.3) << count << " rays";
  }
}

TEST(Triangulation, ChiSquareQuantile) {
  EXPECT_NEAR(chi_square_quantile(0.99, 2), 9.2103, 1e-3);
  EXPECT_NEAR(chi_square_quantile(0.999, 3), 16.266, 1e-3);
  EXPECT_NEAR(chi_square_quantile(0.99, 1), 6.635, 1e-3);
  EXPECT_NEAR(chi_square_quantile(0.95, 10), 18.307, 1e-3);
  EXPECT_NEAR(chi_square_quantile(0.95, 9), 16.919, 1e-3);
}

}  // namespace
}  // namespace dronetrack::fusion::triangulation_test
