// The DOA likelihood's gate, cost and reweighting against closed forms.
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
  EXPECT_NEAR(DoaLikelihood(LikelihoodKind::gaussian, 10.0, 0.999).gate_d2(), 13.8155, 1e-3);
  // d^2 / 2 ~ F(2, dof): dof ((1 - p)^(-2 / dof) - 1).
  EXPECT_NEAR(DoaLikelihood(LikelihoodKind::student_t, 4.0, 0.999).gate_d2(),
              4.0 * (std::sqrt(1000.0) - 1.0), 1e-9);
  EXPECT_NEAR(DoaLikelihood(LikelihoodKind::student_t, 10.0, 0.999).gate_d2(),
              10.0 * (std::pow(1000.0, 0.2) - 1.0), 1e-9);
  // Many degrees of freedom: the Student-t tends to the Gaussian.
  EXPECT_NEAR(DoaLikelihood(LikelihoodKind::student_t, 1e6, 0.999).gate_d2(), 13.8155, 1e-3);
}

TEST(DoaLikelihood, OutlierWeightIsTheFixedPoint) {
  // With S = R / w: w = (dof + 2) / (dof + w d0^2), so w = (-dof + sqrt(dof^2 + 4 d0^2 (dof + 2)))
  // / (2 d0^2). d0^2 = 100, dof = 10: w = 0.3.
  const DoaLikelihood likelihood(LikelihoodKind::student_t, 10.0, 0.999);
  Innovation innovation = noise_only(1e-4);
  const Measurement z(std::sqrt(50.0) * 1e-2, std::sqrt(50.0) * 1e-2);  // d0^2 = 100
  const double weight = likelihood.reweight(innovation, z);
  EXPECT_NEAR(weight, 0.3, 1e-6);
  EXPECT_TRUE(innovation.noise.isApprox(MeasurementCovariance::Identity() * 1e-4 / 0.3, 1e-6));
  EXPECT_TRUE(innovation.covariance.isApprox(innovation.noise, 1e-9));
}

TEST(DoaLikelihood, InliersAndTheGaussianAreLeftAlone) {
  const Measurement z(1e-2, 0.0);  // d^2 = 1 under R = 1e-4
  for (LikelihoodKind kind : {LikelihoodKind::student_t, LikelihoodKind::gaussian}) {
    Innovation innovation = noise_only(1e-4);
    EXPECT_EQ(DoaLikelihood(kind, 10.0, 0.999).reweight(innovation, z), 1.0);
    EXPECT_EQ(innovation.noise, MeasurementCovariance::Identity() * 1e-4);
  }
  Innovation far = noise_only(1e-4);
  EXPECT_EQ(DoaLikelihood(LikelihoodKind::gaussian, 10.0, 0.999).reweight(far, Measurement(1, 1)),
            1.0);
}

TEST(DoaLikelihood, StudentCostGrowsSlowlyInTheTail) {
  const DoaLikelihood gaussian(LikelihoodKind::gaussian, 10.0, 0.999);
  const DoaLikelihood student(LikelihoodKind::student_t, 10.0, 0.999);
  EXPECT_DOUBLE_EQ(gaussian.assignment_cost(9.0, -20.0), 9.0 - 20.0);
  EXPECT_NEAR(student.assignment_cost(9.0, -20.0), 12.0 * std::log1p(0.9) - 20.0, 1e-12);
  EXPECT_LT(student.assignment_cost(25.0, 0.0) - student.assignment_cost(16.0, 0.0),
            gaussian.assignment_cost(25.0, 0.0) - gaussian.assignment_cost(16.0, 0.0));
  EXPECT_LT(student.assignment_cost(1.0, 0.0), student.assignment_cost(2.0, 0.0));
}

}  // namespace
}  // namespace dronetrack::fusion
