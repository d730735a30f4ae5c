// The DOA likelihoods' gates, costs and weights against closed forms.
#include "fusion/doa_likelihood.hpp"

#include <cmath>

#include <gtest/gtest.h>

namespace dronetrack::fusion::doa_likelihood_test {
namespace {

// An innovation whose state part is zero: S = R = diag(r), so d^2(w) = w * d0^2.
Innovation noise_only(double r) {
  Innovation innovation;
  innovation.predicted = Measurement::Zero();
  innovation.noise = MeasurementCovariance::Identity() * r;
  innovation.covariance = innovation.noise;
  return innovation;
}

TEST(DoaLikelihood, GatesAreEachLawsQuantile) {
  EXPECT_NEAR(DoaLikelihood(DoaLikelihoodKind::gaussian, 10.0, 0.0, 0.999).gate_d2(), 13.8155,
              1e-3);
  // d^2 / 2 ~ F(2, dof): dof ((1 - p)^(-2 / dof) - 1).
  EXPECT_NEAR(DoaLikelihood(DoaLikelihoodKind::student_t, 4.0, 0.0, 0.999).gate_d2(),
              4.0 * (std::sqrt(1000.0) - 1.0), 1e-9);
  EXPECT_NEAR(DoaLikelihood(DoaLikelihoodKind::student_t, 10.0, 0.0, 0.999).gate_d2(),
              10.0 * (std::pow(1000.0, 0.2) - 1.0), 1e-9);
  // Many degrees of freedom: the Student-t tends to the Gaussian.
  EXPECT_NEAR(DoaLikelihood(DoaLikelihoodKind::student_t, 1e6, 0.0, 0.999).gate_d2(), 13.8155,
              1e-3);
}

TEST(DoaLikelihood, OutlierWeightIsTheFixedPoint) {
  // With S = R / w: w = (dof + 2) / (dof + w d0^2), so w = (-dof + sqrt(dof^2 + 4 d0^2 (dof + 2)))
  // / (2 d0^2). d0^2 = 100, dof = 10: w = 0.3.
  const DoaLikelihood likelihood(DoaLikelihoodKind::student_t, 10.0, 0.0, 0.999);
  Innovation innovation = noise_only(1e-4);
  const Measurement z(std::sqrt(50.0) * 1e-2, std::sqrt(50.0) * 1e-2);  // d0^2 = 100
  EXPECT_EQ(likelihood.weigh(innovation, z), 1.0);  // the Student-t widens R instead
  EXPECT_TRUE(innovation.noise.isApprox(MeasurementCovariance::Identity() * 1e-4 / 0.3, 1e-6));
  EXPECT_TRUE(innovation.covariance.isApprox(innovation.noise, 1e-9));
}

TEST(DoaLikelihood, InliersAndTheGaussianAreLeftAlone) {
  const Measurement z(1e-2, 0.0);  // d^2 = 1 under R = 1e-4
  for (DoaLikelihoodKind kind : {DoaLikelihoodKind::student_t, DoaLikelihoodKind::gaussian}) {
    Innovation innovation = noise_only(1e-4);
    EXPECT_EQ(DoaLikelihood(kind, 10.0, 0.0, 0.999).weigh(innovation, z), 1.0);
    EXPECT_EQ(innovation.noise, MeasurementCovariance::Identity() * 1e-4);
  }
  Innovation far = noise_only(1e-4);
  EXPECT_EQ(
      DoaLikelihood(DoaLikelihoodKind::gaussian, 10.0, 0.0, 0.999).weigh(far, Measurement(1, 1)),
      1.0);
}

// (1 - e) N(nu; 0, S) + e / (pi gamma sqrt(det S)): the inlier probability at d^2 is
// 1 / (1 + kappa exp(d^2 / 2)), kappa = e / (1 - e) * 2 / gamma, whatever S is.
TEST(DoaLikelihood, MixtureInlierProbabilityIsBayes) {
  const double e = 0.1;
  const DoaLikelihood mixture(DoaLikelihoodKind::outlier_mixture, 10.0, e, 0.999);
  EXPECT_NEAR(mixture.gate_d2(), 13.8155, 1e-3);  // the Gaussian part's chi-square gate
  EXPECT_NEAR(mixture.gate_d2(1), 10.8276, 1e-3);
  const double gamma = mixture.gate_d2();
  for (double r : {1e-6, 1e-4, 1e-2}) {
    for (double d2 : {0.0, 1.0, 9.0, 13.0}) {
      Innovation innovation = noise_only(r);
      const Measurement z(std::sqrt(d2 * r), 0.0);
      const double inlier = (1.0 - e) * std::exp(-0.5 * d2) / (2.0 * M_PI * r);
      const double outlier = e / (M_PI * gamma * r);
      EXPECT_NEAR(mixture.weigh(innovation, z), inlier / (inlier + outlier), 1e-12);
      EXPECT_EQ(innovation.noise, MeasurementCovariance::Identity() * r);  // R untouched
      // The adaptive e's g: the uniform part over the Gaussian part, per unit of the odds.
      EXPECT_NEAR(mixture.outlier_density_ratio(d2, 2) * e / (1.0 - e), outlier / inlier,
                  1e-9 * outlier / inlier);
      // Twice the negative log of the same density, up to a constant.
      EXPECT_NEAR(
          mixture.assignment_cost(d2, std::log(r * r)) - mixture.assignment_cost(0.0, 0.0),
          -2.0 * std::log((inlier + outlier) / ((1.0 - e) / (2.0 * M_PI) + e / (M_PI * gamma))),
          1e-9);
    }
  }
  // No outliers expected: the Gaussian.
  const DoaLikelihood none(DoaLikelihoodKind::outlier_mixture, 10.0, 0.0, 0.999);
  Innovation innovation = noise_only(1e-4);
  EXPECT_EQ(none.weigh(innovation, Measurement(3e-2, 0.0)), 1.0);
  EXPECT_DOUBLE_EQ(none.assignment_cost(9.0, -20.0), 9.0 - 20.0);
}

TEST(DoaLikelihood, MixtureOnACone) {
  // Interval of half-width sqrt(gamma_1 S): kappa = e / (1 - e) sqrt(2 pi) / (2 sqrt(gamma_1)).
  const double e = 0.2;
  const DoaLikelihood mixture(DoaLikelihoodKind::outlier_mixture, 10.0, e, 0.999);
  const DoaMeasurementModel cone{{0, 0, 0}, 343.0, 0, MeasurementKind::cone};
  Innovation innovation = noise_only(1e-4);
  innovation.model = &cone;
  innovation.noise(1, 1) = innovation.covariance(1, 1) = 1.0;  // the pad
  const double kappa =
      e / (1.0 - e) * std::sqrt(2.0 * M_PI) / (2.0 * std::sqrt(mixture.gate_d2(1)));
  const double d2 = 4.0;
  EXPECT_NEAR(mixture.weigh(innovation, Measurement(std::sqrt(d2 * 1e-4), 0.0)),
              1.0 / (1.0 + kappa * std::exp(0.5 * d2)), 1e-12);
}

TEST(DoaLikelihood, StudentCostGrowsSlowlyInTheTail) {
  const DoaLikelihood gaussian(DoaLikelihoodKind::gaussian, 10.0, 0.0, 0.999);
  const DoaLikelihood student(DoaLikelihoodKind::student_t, 10.0, 0.0, 0.999);
  EXPECT_DOUBLE_EQ(gaussian.assignment_cost(9.0, -20.0), 9.0 - 20.0);
  EXPECT_NEAR(student.assignment_cost(9.0, -20.0), 12.0 * std::log1p(0.9) - 20.0, 1e-12);
  EXPECT_LT(student.assignment_cost(25.0, 0.0) - student.assignment_cost(16.0, 0.0),
            gaussian.assignment_cost(25.0, 0.0) - gaussian.assignment_cost(16.0, 0.0));
  EXPECT_LT(student.assignment_cost(1.0, 0.0), student.assignment_cost(2.0, 0.0));
}

}  // namespace
}  // namespace dronetrack::fusion::doa_likelihood_test
