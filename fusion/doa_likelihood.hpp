#pragma once
// The DOA measurement likelihood every Gaussian filter updates with, and the gate and assignment
// cost that must agree with it (issue 17). Acoustic DOAs have heavy tails: a reflection, a gust,
// a second source captured for one frame. Two choices (`fusion.likelihood`):
//   gaussian   the filters' own: chi-square gate at gate_probability, cost d^2 + ln det S;
//   student_t  a multivariate Student-t of `dof` degrees of freedom on the innovation: the gate is
//              its own quantile at gate_probability (d^2 / p follows F(p, dof)), the cost twice its
//              negative log-likelihood, and the update is the Gaussian update with the DOA's noise
//              R divided by the weight w = (dof + p) / (dof + d^2), iterated to its fixed point
//              (the EM / iteratively reweighted form of the Student-t update). w is capped at 1: an
//              inlier is taken as the Gaussian would take it, an outlier counts for less.
// p is the measurement's dimension: 2 for a direction, 1 for a two-mic array's cone angle (issue
// 15), so a cone is gated and costed with its own degrees of freedom.
// Plain arithmetic on the innovation; no filter internals, so UKF, EKF and the IMM all get it.
#include "fusion/state.hpp"
#include "fusion/track_filter.hpp"

namespace dronetrack::fusion {

enum class LikelihoodKind { gaussian, student_t };

class DoaLikelihood {
 public:
  DoaLikelihood(LikelihoodKind kind, double dof, double gate_probability);

  LikelihoodKind kind() const { return kind_; }
  // Squared Mahalanobis distance beyond which a DOA of `dimension` (1 or 2) is not this track's.
  double gate_d2(int dimension = 2) const { return dimension == 1 ? gate_d2_1d_ : gate_d2_; }
  // Twice the negative log-likelihood up to a constant, for the assignment.
  double assignment_cost(double d2, double log_det_covariance, int dimension = 2) const;
  // Student-t: rescales the noise part of `innovation` (its covariance and noise) for the update
  // of `z` and returns the weight given to the DOA (1: as the Gaussian). Gaussian: returns 1.
  double reweight(Innovation& innovation, const Measurement& z) const;

 private:
  LikelihoodKind kind_;
  double dof_;
  double gate_d2_;
  double gate_d2_1d_;
};

}  // namespace dronetrack::fusion
