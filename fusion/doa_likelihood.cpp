#include "fusion/doa_likelihood.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <Eigen/Cholesky>

#include "fusion/triangulation.hpp"

namespace dronetrack::fusion {
namespace {
constexpr int kBisections = 30;  // the weight to 1e-9
// The particle filter's outlier share under the gaussian kind (a uniform DOA over the sphere).
constexpr double kSphereOutlierProbability = 0.05;

// Quantile of t^2 for a Student-t of `dof` degrees of freedom (d^2 of a 1-D innovation, which
// follows F(1, dof)): P(|t| <= T) by Simpson's rule on the density, bisection on T. Once, at
// construction.
double student_t_square_quantile(double probability, double dof) {
  const double log_norm = std::lgamma(0.5 * (dof + 1.0)) - std::lgamma(0.5 * dof) -
                          0.5 * std::log(dof * std::numbers::pi);
  const auto density = [&](double t) {
    return std::exp(log_norm - 0.5 * (dof + 1.0) * std::log1p(t * t / dof));
  };
  const auto central = [&](double limit) {  // P(|t| <= limit)
    constexpr int kIntervals = 4000;
    const double h = limit / kIntervals;
    double sum = density(0.0) + density(limit);
    for (int i = 1; i < kIntervals; ++i) sum += (i % 2 == 1 ? 4.0 : 2.0) * density(i * h);
    return 2.0 * sum * h / 3.0;
  };
  double low = 0.0;
  double high = 1.0;
  while (central(high) < probability && high < 1e6) high *= 2.0;
  for (int i = 0; i < 60; ++i) {
    const double middle = 0.5 * (low + high);
    (central(middle) < probability ? low : high) = middle;
  }
  const double limit = 0.5 * (low + high);
  return limit * limit;
}
}  // namespace

DoaLikelihood::DoaLikelihood() : DoaLikelihood(DoaLikelihoodKind::gaussian, 10.0, 0.0, 0.999) {}

DoaLikelihood::DoaLikelihood(DoaLikelihoodKind kind, double student_t_dof,
                             double outlier_probability, double gate_probability)
    : kind_(kind), dof_(student_t_dof), outlier_probability_(outlier_probability) {
  if (!(gate_probability > 0.0 && gate_probability < 1.0))
    throw std::invalid_argument("gate_probability must be in (0, 1)");
  if (kind_ == DoaLikelihoodKind::student_t && !(dof_ >= 1.0))
    throw std::invalid_argument("student_t_dof must be >= 1");
  if (kind_ == DoaLikelihoodKind::outlier_mixture &&
      !(outlier_probability_ >= 0.0 && outlier_probability_ < 1.0))
    throw std::invalid_argument("outlier_probability must be in [0, 1)");
  if (kind_ == DoaLikelihoodKind::student_t) {
    // P(d^2 / 2 <= x) = 1 - (1 + 2 x / dof)^(-dof / 2) for F(2, dof).
    gate_d2_ = dof_ * (std::pow(1.0 - gate_probability, -2.0 / dof_) - 1.0);
    gate_d2_1d_ = student_t_square_quantile(gate_probability, dof_);
  } else {
    gate_d2_ = chi_square_quantile(gate_probability, 2);
    gate_d2_1d_ = chi_square_quantile(gate_probability, 1);
  }
  // (2 pi) / (pi gamma) for an ellipse; sqrt(2 pi) / (2 sqrt(gamma)) for an interval.
  ratio_per_odds_ = 2.0 / gate_d2_;
  ratio_per_odds_1d_ = std::sqrt(2.0 * std::numbers::pi) / (2.0 * std::sqrt(gate_d2_1d_));
}

double DoaLikelihood::inlier_probability(double d2, double kappa) {
  const double inlier = std::exp(-0.5 * d2);
  const double total = inlier + kappa;
  return total > 0.0 ? inlier / total : 0.0;
}

double DoaLikelihood::assignment_cost(double d2, double log_det_covariance, int dimension,
                                      std::optional<double> outlier_probability) const {
  switch (kind_) {
    case DoaLikelihoodKind::gaussian:
      break;
    case DoaLikelihoodKind::student_t:
      return (dof_ + dimension) * std::log1p(d2 / dof_) + log_det_covariance;
    case DoaLikelihoodKind::outlier_mixture: {
      // -2 ln(exp(-d^2 / 2) + kappa) = d^2 - 2 ln(1 + kappa exp(d^2 / 2)): the Gaussian's cost
      // near the prediction, flattening towards the gate.
      const double kappa = outlier_ratio(dimension, outlier_probability);
      if (kappa > 0.0)
        return d2 - 2.0 * std::log1p(kappa * std::exp(0.5 * d2)) + log_det_covariance;
      break;
    }
  }
  return d2 + log_det_covariance;
}

double DoaLikelihood::weigh(Innovation& innovation, const Measurement& z) const {
  if (kind_ == DoaLikelihoodKind::gaussian) return 1.0;
  const Measurement residual = innovation.residual(z);
  if (kind_ == DoaLikelihoodKind::outlier_mixture) {
    return inlier_probability(
        residual.dot(innovation.covariance.ldlt().solve(residual)),
        outlier_ratio(innovation.dimension(), innovation.outlier_probability));
  }
  const MeasurementCovariance state_part = innovation.covariance - innovation.noise;
  const MeasurementCovariance noise = innovation.noise;
  const double p = innovation.dimension();
  // The weight solves w = (dof + p) / (dof + d^2(w)), d^2(w) = r' (state_part + R / w)^-1 r.
  // d^2 grows with w, so w - (dof + p) / (dof + d^2(w)) grows with w: bisection finds the one
  // root (plain iteration of the fixed point oscillates for large residuals).
  // A cone's pad slot (state.hpp) keeps its unit variance.
  const auto scaled_noise = [&](double weight) {
    MeasurementCovariance scaled = noise / weight;
    if (innovation.dimension() == 1) scaled(1, 1) = noise(1, 1);
    return scaled;
  };
  const auto excess = [&](double weight) {
    const MeasurementCovariance covariance = state_part + scaled_noise(weight);
    const double d2 = residual.dot(covariance.ldlt().solve(residual));
    return weight - (dof_ + p) / (dof_ + d2);
  };
  const double at_one = excess(1.0);
  if (!std::isfinite(at_one) || at_one <= 0.0) return 1.0;  // an inlier: as the Gaussian
  double low = 0.0;
  double high = 1.0;
  for (int i = 0; i < kBisections; ++i) {
    const double middle = 0.5 * (low + high);
    (excess(std::max(middle, 1e-12)) < 0.0 ? low : high) = middle;
  }
  const double weight = std::max(high, 1e-12);
  innovation.covariance = state_part + scaled_noise(weight);
  innovation.noise = scaled_noise(weight);
  return 1.0;
}

double DoaLikelihood::particle_kernel(double d2_under_noise, int dimension,
                                      std::optional<double> outlier_probability) const {
  switch (kind_) {
    case DoaLikelihoodKind::gaussian:
      break;
    case DoaLikelihoodKind::student_t:
      return std::pow(1.0 + d2_under_noise / dof_, -0.5 * (dof_ + dimension));
    case DoaLikelihoodKind::outlier_mixture:
      return (1.0 - outlier_probability.value_or(outlier_probability_)) *
             std::exp(-0.5 * d2_under_noise);
  }
  return std::exp(-0.5 * d2_under_noise);
}

double DoaLikelihood::particle_floor(const Innovation& innovation) const {
  // The pad of a cone's R and S is 1: det is its one variance.
  const double det_noise = innovation.noise.determinant();
  const int dimension = innovation.dimension();
  switch (kind_) {
    case DoaLikelihoodKind::gaussian:
      // 1 / (4 pi) over the sphere for a direction, 1 / pi over [0, pi] for a cone angle.
      return dimension == 2 ? kSphereOutlierProbability * std::sqrt(det_noise) / 2.0
                            : kSphereOutlierProbability *
                                  std::sqrt(2.0 * std::numbers::pi * det_noise) / std::numbers::pi;
    case DoaLikelihoodKind::student_t:
      return 0.0;
    case DoaLikelihoodKind::outlier_mixture: {
      const double det_covariance = innovation.covariance.determinant();
      if (!(det_covariance > 0.0)) return 0.0;
      const std::optional<double> share = innovation.outlier_probability;
      return (1.0 - share.value_or(outlier_probability_)) * outlier_ratio(dimension, share) *
             std::sqrt(det_noise / det_covariance);
    }
  }
  return 0.0;
}

}  // namespace dronetrack::fusion
