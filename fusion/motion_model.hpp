#pragma once
// Constant-jerk motion model (SPEC 4.5; seed 002 eqs. 14-18 with the block form of F: the seed's
// row 6 has a misplaced T). Per axis, state [p, v, a]:
//   F = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]],  Gamma = [T^3/6, T^2/2, T]^T,  Q = Gamma q Gamma^T
// with q the jerk variance. The model is linear, so every filter predicts with it exactly.
#include "fusion/state.hpp"

namespace dronetrack::fusion {

struct ConstantJerkModel {
  double jerk_variance_m2ps6 = 9.0;  // q

  StateCovariance transition(double dt_s) const;     // F
  StateCovariance process_noise(double dt_s) const;  // Q
  // Gamma as a 9x3 matrix: column k drives axis k.
  Eigen::Matrix<double, kStateSize, 3> noise_gain(double dt_s) const;
  // x <- F x, P <- F P F^T + Q.
  void predict(StateVector& x, StateCovariance& covariance, double dt_s) const;
  // The mean only (used for the emission-time back-propagation and particles).
  static StateVector propagate(const StateVector& x, double dt_s);
};

}  // namespace dronetrack::fusion
