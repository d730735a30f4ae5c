#pragma once
// The DOA measurement likelihood (issue 17): every filter weighs a DOA by it in its own update
// (TrackFilter::update), and the tracker gates and assigns by the same law. Acoustic DOAs have
// heavy tails: a reflection, a gust, a second source captured for one frame. Three choices
// (`fusion.likelihood`, docs/fusion.md "Impulsive DOA errors"):
//   outlier_mixture  (default) (1 - e) N(nu; 0, S) + e / V: a DOA is the track's with probability
//                    1 - e, otherwise uniform over the gate's ellipse d^2 <= gamma (area V). The
//                    gate is the Gaussian part's chi-square quantile at gate_probability, so gate
//                    and likelihood agree: beyond it a DOA can only be the uniform part, whose
//                    density does not depend on the state, so dropping it is exact. Inside it the
//                    update is the mixture posterior's first two moments (a one-measurement PDA):
//                    the Kalman correction times the inlier probability beta(d^2), the covariance
//                    widened by the spread between "inlier" and "outlier". beta depends on d^2
//                    alone (V grows with sqrt det S as the Gaussian's peak falls).
//   student_t        a multivariate Student-t of `dof` degrees of freedom: its own gate quantile
//                    (d^2 / p follows F(p, dof)), twice its negative log-likelihood as the cost,
//                    and the Gaussian update with R divided by w = (dof + p) / (dof + d^2),
//                    iterated to its fixed point (bisection), w capped at 1.
//   gaussian         chi-square gate, cost d^2 + ln det S, the plain Kalman update.
// p is the measurement's dimension: 2 for a direction, 1 for a two-mic array's cone angle (issue
// 15), so a cone is gated and costed with its own degrees of freedom.
// Plain arithmetic on the innovation: no filter internals, nothing allocated.
#include <cmath>
#include <optional>

#include "fusion/fusion_params.hpp"
#include "fusion/innovation.hpp"
#include "fusion/state.hpp"

namespace dronetrack::fusion {

class DoaLikelihood {
 public:
  DoaLikelihood();  // gaussian, gate 0.999
  DoaLikelihood(DoaLikelihoodKind kind, double student_t_dof, double outlier_probability,
                double gate_probability);

  DoaLikelihoodKind kind() const { return kind_; }
  // Squared Mahalanobis distance beyond which a DOA of `dimension` (1 or 2) is not this track's.
  double gate_d2(int dimension = 2) const { return dimension == 1 ? gate_d2_1d_ : gate_d2_; }
  // Twice the negative log-likelihood of a DOA at d^2 under an innovation covariance S, up to a
  // constant: the assignment cost. The IMM weighs its modes by -1/2 of it.
  // outlier_probability: the DOA's e when the tracker estimates it (Innovation::
  // outlier_probability); unset: the configured one.
  double assignment_cost(double d2, double log_det_covariance, int dimension = 2,
                         std::optional<double> outlier_probability = std::nullopt) const;
  // Prepares `innovation` for the filter's update of `z` and returns the inlier probability beta
  // the Kalman correction is scaled by (1 for gaussian and student_t), at the innovation's e when
  // it carries one. student_t rescales the noise part of the innovation (covariance and noise)
  // instead.
  double weigh(Innovation& innovation, const Measurement& z) const;
  // The particle filter's density of z for a particle whose residual has d^2 under R (not S),
  // scaled by (2 pi)^(p/2) sqrt(det R) (the same for every particle)...
  double particle_kernel(double d2_under_noise, int dimension,
                         std::optional<double> outlier_probability = std::nullopt) const;
  // ...plus this floor at the same scale: the uniform part over the gate of the cloud's S
  // (outlier_mixture), a uniform DOA over the sphere with probability 0.05 (gaussian: a cloud
  // must not collapse on one wild DOA), 0 (student_t: its tails do that).
  double particle_floor(const Innovation& innovation) const;

  // The configured e (outlier_mixture): the adaptive estimate's prior mean.
  double outlier_probability() const { return outlier_probability_; }
  // The uniform part's density over the Gaussian part's at d^2, per unit of the odds e / (1 - e):
  // (2 pi)^(p/2) sqrt(det S) / V exp(d^2 / 2): (2 / gamma) exp(d^2 / 2) for a direction,
  // sqrt(2 pi) / (2 sqrt gamma) exp(d^2 / 2) for a cone, whatever S. One gated DOA's whole say on
  // e (outlier_share.hpp): its likelihood is proportional to 1 - e + e g.
  double outlier_density_ratio(double d2, int dimension) const {
    return ratio_per_odds(dimension) * std::exp(0.5 * d2);
  }

 private:
  // Inlier probability at d^2: exp(-d^2 / 2) / (exp(-d^2 / 2) + kappa).
  static double inlier_probability(double d2, double kappa);
  // kappa / odds: the same for every S (the uniform part's density and the Gaussian's peak both
  // scale with 1 / sqrt(det S)).
  double ratio_per_odds(int dimension) const {
    return dimension == 1 ? ratio_per_odds_1d_ : ratio_per_odds_;
  }
  // kappa at the given e, or at the configured one.
  double outlier_ratio(int dimension, std::optional<double> outlier_probability) const {
    const double e = outlier_probability.value_or(outlier_probability_);
    return e / (1.0 - e) * ratio_per_odds(dimension);
  }

  DoaLikelihoodKind kind_ = DoaLikelihoodKind::gaussian;
  double dof_ = 10.0;
  double outlier_probability_ = 0.0;
  double gate_d2_ = 0.0;
  double gate_d2_1d_ = 0.0;
  // kappa = e / (1 - e) * (2 pi)^(p/2) / (c_p gamma^(p/2)), c_2 = pi, c_1 = 2:
  // the uniform part's density over the Gaussian part's peak (both scale with 1 / sqrt(det S),
  // which cancels).
  double ratio_per_odds_ = 0.0;  // kappa / odds: 2 / gamma, sqrt(2 pi) / (2 sqrt gamma)
  double ratio_per_odds_1d_ = 0.0;
};

}  // namespace dronetrack::fusion
