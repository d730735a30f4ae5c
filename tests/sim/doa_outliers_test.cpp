// Impulsive DOA errors: the share perturbed, the error law, determinism.
#include "sim/doa_outliers.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "doa/array_geometry.hpp"

namespace dronetrack::sim::doa_outliers_test {
namespace {

std::vector<doa::DoaMeasurement> level_doas(int count) {
  std::vector<doa::DoaMeasurement> doas(static_cast<std::size_t>(count));
  for (auto& doa : doas) doa.direction = doa::direction_from_azel_deg(30.0, 10.0);
  return doas;
}

TEST(DoaOutliers, PerturbsTheShareAsked) {
  auto doas = level_doas(20000);
  DoaOutlierSettings settings;
  settings.share = 0.3;
  const std::size_t perturbed = add_doa_outliers(doas, settings);
  EXPECT_NEAR(perturbed / 20000.0, 0.3, 0.015);
  std::size_t moved = 0;
  for (const auto& doa : doas) moved += std::abs(doa::azimuth_deg(doa.direction) - 30.0) > 1e-9;
  EXPECT_EQ(moved, perturbed);
}

TEST(DoaOutliers, GaussianLawGivesItsSpread) {
  // alpha 2: each angle's error is Gaussian of std scale * sqrt(2).
  auto doas = level_doas(20000);
  DoaOutlierSettings settings;
  settings.share = 1.0;
  settings.law_deg = {2.0, 0.0, 1.0, 0.0};
  add_doa_outliers(doas, settings);
  double sum = 0.0, sum_squares = 0.0;
  for (const auto& doa : doas) {
    const double error = doa::azimuth_deg(doa.direction) - 30.0;
    sum += error;
    sum_squares += error * error;
  }
  const double mean = sum / 20000.0;
  EXPECT_NEAR(mean, 0.0, 0.05);
  EXPECT_NEAR(std::sqrt(sum_squares / 20000.0 - mean * mean), std::sqrt(2.0), 0.05);
}

TEST(DoaOutliers, SameSeedSameOutliersNoneWithoutShare) {
  auto first = level_doas(100);
  auto second = level_doas(100);
  DoaOutlierSettings settings;
  settings.share = 0.5;
  add_doa_outliers(first, settings);
  add_doa_outliers(second, settings);
  for (std::size_t i = 0; i < first.size(); ++i) EXPECT_EQ(first[i].direction, second[i].direction);
  auto untouched = level_doas(100);
  settings.share = 0.0;
  EXPECT_EQ(add_doa_outliers(untouched, settings), 0u);
  settings.share = 1.5;
  EXPECT_THROW(add_doa_outliers(untouched, settings), std::invalid_argument);
}

}  // namespace
}  // namespace dronetrack::sim::doa_outliers_test
