// The alpha-stable sampler against closed forms: the Gaussian (alpha 2), Cauchy (alpha 1, beta 0)
// and Levy (alpha 1/2, beta 1) quantiles, and the characteristic function of seed 001's skewed
// law (alpha 1.8, beta 1), which has no closed-form quantiles.
#include "sim/alpha_stable.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

namespace dronetrack::sim::alpha_stable_test {
namespace {

constexpr int kDraws = 200000;

std::vector<double> draws(const AlphaStable& law, std::uint64_t seed) {
  Random random(seed, 1);
  std::vector<double> out(kDraws);
  for (double& value : out) value = draw_alpha_stable(law, random);
  std::sort(out.begin(), out.end());
  return out;
}

double quantile(const std::vector<double>& sorted, double p) {
  return sorted[static_cast<std::size_t>(p * static_cast<double>(sorted.size() - 1))];
}

// Inverse of a increasing function on [low, high] by bisection.
template <typename F>
double invert(F f, double target, double low, double high) {
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (low + high);
    (f(mid) < target ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

double standard_normal_quantile(double p) {
  return invert([](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }, p, -10.0, 10.0);
}

const double kProbabilities[] = {0.1, 0.25, 0.5, 0.75, 0.9};

TEST(AlphaStable, AlphaTwoIsGaussianOfVarianceTwoScaleSquared) {
  const AlphaStable law{2.0, 0.0, 1.5, -3.0};
  const auto sorted = draws(law, 11);
  for (double p : kProbabilities) {
    const double expected = -3.0 + 1.5 * std::sqrt(2.0) * standard_normal_quantile(p);
    EXPECT_NEAR(quantile(sorted, p), expected, 0.02) << "p " << p;
  }
}

TEST(AlphaStable, AlphaOneBetaZeroIsCauchy) {
  const AlphaStable law{1.0, 0.0, 2.0, 1.0};
  const auto sorted = draws(law, 12);
  for (double p : kProbabilities) {
    const double expected = 1.0 + 2.0 * std::tan(std::numbers::pi * (p - 0.5));
    EXPECT_NEAR(quantile(sorted, p), expected, 0.03 * std::max(1.0, std::abs(expected)))
        << "p " << p;
  }
}

TEST(AlphaStable, AlphaHalfBetaOneIsLevy) {
  // Levy(mu, c): F(x) = erfc(sqrt(c / (2 (x - mu)))), support x > mu.
  const AlphaStable law{0.5, 1.0, 0.8, 0.5};
  const auto sorted = draws(law, 13);
  EXPECT_GT(sorted.front(), 0.5);  // totally skewed: nothing left of mu
  for (double p : kProbabilities) {
    const double s = invert([](double x) { return -std::erfc(x); }, -p, 0.0, 10.0);
    const double expected = 0.5 + 0.8 / (2.0 * s * s);
    EXPECT_NEAR(quantile(sorted, p), expected, 0.03 * expected) << "p " << p;
  }
}

TEST(AlphaStable, SeedOneLawHasItsCharacteristicFunction) {
  // E exp(i t X) = exp(-(c|t|)^a (1 - i b sign(t) tan(pi a / 2)) + i mu t), a != 1.
  const AlphaStable law{1.8, 1.0, 10.0, -3.0};
  for (double t : {0.02, 0.05, 0.1}) {
    std::complex<double> empirical = 0.0;
    Random stream(15, static_cast<std::uint64_t>(t * 1000));
    for (int i = 0; i < kDraws; ++i)
      empirical += std::exp(std::complex<double>(0.0, t * draw_alpha_stable(law, stream)));
    empirical /= static_cast<double>(kDraws);
    const double power = std::pow(law.scale * t, law.alpha);
    const std::complex<double> expected = std::exp(std::complex<double>(
        -power,
        power * law.beta * std::tan(0.5 * std::numbers::pi * law.alpha) + law.location * t));
    EXPECT_NEAR(empirical.real(), expected.real(), 0.01) << "t " << t;
    EXPECT_NEAR(empirical.imag(), expected.imag(), 0.01) << "t " << t;
  }
}

TEST(AlphaStable, MixtureDrawsTheImpulsiveShare) {
  // Impulses of a scale far beyond the Gaussian's are counted by size.
  const AlphaStable law{1.0, 0.0, 1000.0, 0.0};
  Random random(16, 1);
  int large = 0;
  constexpr int kCount = 100000;
  for (int i = 0; i < kCount; ++i)
    large += std::abs(draw_impulsive_mixture(0.3, 1.0, law, random)) > 10.0;
  // A Cauchy of scale 1000 exceeds 10 with probability 1 - 2 atan(0.01) / pi = 0.9936.
  EXPECT_NEAR(large / static_cast<double>(kCount), 0.3 * 0.9936, 0.006);
}

TEST(AlphaStable, RefusesParametersOutsideTheirRanges) {
  Random random(17, 1);
  EXPECT_THROW(draw_alpha_stable({2.5, 0.0, 1.0, 0.0}, random), std::invalid_argument);
  EXPECT_THROW(draw_alpha_stable({1.5, 1.5, 1.0, 0.0}, random), std::invalid_argument);
  EXPECT_THROW(draw_alpha_stable({1.5, 0.0, 0.0, 0.0}, random), std::invalid_argument);
}

}  // namespace
}  // namespace dronetrack::sim::alpha_stable_test
