#include "fusion/outlier_share.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "fusion/doa_likelihood.hpp"

namespace dronetrack::fusion::outlier_share_test {
namespace {

// Gated DOAs drawn from the outlier mixture itself (a direction, gate 0.999): an inlier's d^2 is
// chi-square with 2 dof below the gate, an outlier is uniform over the gate's ellipse, so its d^2
// is uniform on [0, gamma]. `share` of them outliers.
void feed(OutlierShareEstimate& estimate, const DoaLikelihood& law, double share, int count,
          std::mt19937_64& random) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const double gate = law.gate_d2(2);
  for (int k = 0; k < count; ++k) {
    double d2 = 0.0;
    if (uniform(random) < share) {
      d2 = gate * uniform(random);
    } else {
      do d2 = -2.0 * std::log1p(-uniform(random));  // chi-square, 2 dof
      while (d2 > gate);
    }
    estimate.add(law.outlier_density_ratio(d2, 2));
    estimate.refresh();  // as the tracker does after each frame
  }
}

// The posterior's maximum over the window finds the injected share: at 0.3 within its sampling
// spread (sd ~0.025 over 500 DOAs), at 0 it settles at the floor the prior leaves (~0.015), well
// below the prior's 0.1; and it follows a change within one window.
TEST(OutlierShareEstimate, FindsTheInjectedShareAndFollowsIt) {
  const DoaLikelihood law(DoaLikelihoodKind::outlier_mixture, 10.0, 0.1, 0.999);
  OutlierShareEstimate estimate(0.1, 10.0, 500);
  EXPECT_DOUBLE_EQ(estimate.share(), 0.1);  // no data: the prior's mean
  estimate.refresh();
  EXPECT_NEAR(estimate.share(), 0.1, 1e-6);
  std::mt19937_64 random(5);
  feed(estimate, law, 0.3, 1000, random);
  EXPECT_NEAR(estimate.share(), 0.3, 0.06);
  feed(estimate, law, 0.0, 500, random);  // one window of clean DOAs
  EXPECT_LT(estimate.share(), 0.03);
  EXPECT_GT(estimate.share(), 0.0);
  feed(estimate, law, 0.1, 500, random);
  EXPECT_NEAR(estimate.share(), 0.1, 0.04);
  EXPECT_EQ(estimate.count(), 500);
}

// A DOA that says nothing (g = 1: the two parts equally likely) leaves the prior; a bad ratio is
// ignored.
TEST(OutlierShareEstimate, UninformativeDoasKeepThePrior) {
  OutlierShareEstimate estimate(0.2, 10.0, 100);
  for (int k = 0; k < 100; ++k) estimate.add(1.0);
  estimate.add(std::nan(""));
  estimate.add(-1.0);
  estimate.refresh();
  EXPECT_NEAR(estimate.share(), 0.2, 1e-6);
  EXPECT_EQ(estimate.count(), 100);
}

}  // namespace
}  // namespace dronetrack::fusion::outlier_share_test
