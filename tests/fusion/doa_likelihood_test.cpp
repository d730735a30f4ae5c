// The DOA likelihoods' gates, costs and weights against closed forms.
#include "fusion/doa_likelihood.hpp"

#include <cmath>

#include <gtest/gtest.h>

namespace dronetrack::fusion {
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

// Outliers spread over a cap of half-angle theta around the source, which lies anywhere in the
// gate: uniform over the sum of the two discs, area (sqrt(A) + sqrt(pi gamma sqrt(det S)))^2,
// A = 2 pi (1 - cos theta). A sharp track (S << A) takes a DOA at its gate at almost full gain, a
// vague one (S >> A) discounts it as the gate alone does; theta = 0 is the gate alone.
TEST(DoaLikelihood, SpreadOutliersAreBayesOverTheGrownArea) {
  const double e = 0.1;
  const double theta = 20.0 * M_PI / 180.0;
  const DoaLikelihood spread(DoaLikelihoodKind::outlier_mixture, 10.0, e, 0.999, theta);
  const DoaLikelihood gate_only(DoaLikelihoodKind::outlier_mixture, 10.0, e, 0.999);
  EXPECT_EQ(spread.gate_d2(), gate_only.gate_d2());  // the Gaussian part's gate either way
  const double gamma = spread.gate_d2();
  const double cap_area = 2.0 * M_PI * (1.0 - std::cos(theta));
  for (double r : {1e-8, 1e-6, 1e-4, 1e-2}) {  // S = r I: std 0.006 to 5.7 degrees
    for (double d2 : {0.0, 2.0, 9.0, 13.0}) {
      Innovation innovation = noise_only(r);
      const Measurement z(std::sqrt(d2 * r), 0.0);
      const double side = std::sqrt(cap_area) + std::sqrt(M_PI * gamma * r);
      const double inlier = (1.0 - e) * std::exp(-0.5 * d2) / (2.0 * M_PI * r);
      const double outlier = e / (side * side);
      EXPECT_NEAR(spread.weigh(innovation, z), inlier / (inlier + outlier), 1e-12);
      const double log_det = std::log(r * r);
      EXPECT_NEAR(spread.assignment_cost(d2, log_det) - spread.assignment_cost(0.0, log_det),
                  -2.0 * std::log((inlier + outlier) / ((1.0 - e) / (2.0 * M_PI * r) + outlier)),
                  1e-9);
      EXPECT_NEAR(spread.outlier_density_ratio(d2, log_det, 2) * e / (1.0 - e), outlier / inlier,
                  1e-9 * outlier / inlier);
    }
  }
  // At a 0.3 degree std (a tracked drone) a DOA at the gate keeps most of its gain...
  const double sharp = std::pow(0.3 * M_PI / 180.0, 2);
  Innovation at_gate = noise_only(sharp);
  EXPECT_GT(spread.weigh(at_gate, Measurement(std::sqrt(13.0 * sharp), 0.0)), 0.95);
  at_gate = noise_only(sharp);
  EXPECT_LT(gate_only.weigh(at_gate, Measurement(std::sqrt(13.0 * sharp), 0.0)), 0.1);
  // ...and at 10 degrees (a track just started, S of the cap's size) it keeps a discount of the
  // gate alone's order (here 0.45 of it).
  const double vague = std::pow(10.0 * M_PI / 180.0, 2);
  Innovation wide = noise_only(vague);
  const double spread_beta = spread.weigh(wide, Measurement(std::sqrt(4.0 * vague), 0.0));
  wide = noise_only(vague);
  const double gate_beta = gate_only.weigh(wide, Measurement(std::sqrt(4.0 * vague), 0.0));
  EXPECT_GT(spread_beta, gate_beta);
  EXPECT_GT(1.0 - spread_beta, 0.4 * (1.0 - gate_beta));
}

TEST(DoaLikelihood, SpreadOutliersOnACone) {
  // A cone's interval: the gate's 2 sqrt(gamma_1 S) plus the spread's 2 theta.
  const double e = 0.2;
  const double theta = 0.3;
  const DoaLikelihood mixture(DoaLikelihoodKind::outlier_mixture, 10.0, e, 0.999, theta);
  const DoaMeasurementModel cone{{0, 0, 0}, 343.0, 0, MeasurementKind::cone};
  const double s = 1e-4;
  Innovation innovation = noise_only(s);
  innovation.model = &cone;
  innovation.noise(1, 1) = innovation.covariance(1, 1) = 1.0;  // the pad
  const double d2 = 4.0;
  const double inlier = (1.0 - e) * std::exp(-0.5 * d2) / std::sqrt(2.0 * M_PI * s);
  const double outlier = e / (2.0 * std::sqrt(mixture.gate_d2(1) * s) + 2.0 * theta);
  EXPECT_NEAR(mixture.weigh(innovation, Measurement(std::sqrt(d2 * s), 0.0)),
              inlier / (inlier + outlier), 1e-12);
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
}  // namespace dronetrack::fusion
