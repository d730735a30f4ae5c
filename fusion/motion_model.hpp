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

// Coordinated turn on the same 9 states, so it mixes with the constant-jerk models in the IMM
// (Bar-Shalom, Li & Kirubarajan, Estimation with Applications to Tracking and Navigation, 11.7;
// Blom & Bar-Shalom's IMM CV/CT). The horizontal turn rate is not a state: it is implied by the
// velocity and acceleration, omega = (v_x a_y - v_y a_x) / |v_h|^2, and so is the relative
// tangential acceleration alpha = v_h . a_h / |v_h|^2. Over T the heading turns by omega T and
// the speed changes at a constant rate: v_h(s) = R(omega s) (1 + alpha s) v_h, integrated exactly
// for the position (an exact arc when alpha = 0; constant acceleration when omega = 0), and a_h
// rotates with it. The vertical axis is constant acceleration. Under min_speed_mps the
// denominators are clamped to min_speed_mps^2 and the part of a_h that omega and alpha no longer
// explain is propagated as constant acceleration: at zero speed the model is the constant-jerk
// mean (continuous in the state, so the EKF's Jacobian stays finite).
// Process noise: a small isotropic jerk (Gamma q_j Gamma^T per axis, as the constant-jerk model)
// plus turn-rate noise: omega' white with variance q_w drives a jerk omega' |v_h| along the
// horizontal normal n = (-v_y, v_x, 0): Q_w = q_w (Gamma n)(Gamma n)^T (zero when hovering).
// The model is nonlinear: the UKF predicts through sigma points, the EKF through jacobian()
// (central differences); Q is evaluated at the mean.
struct CoordinatedTurnModel {
  double jerk_variance_m2ps6 = 0.25;        // q_j
  double turn_rate_variance_rad2ps4 = 1.0;  // q_w, of omega' (rad/s^2)
  double min_speed_mps = 0.5;
  // omega is clamped to this (a drone at 5 m/s on a 1.7 m radius); the acceleration it leaves
  // unexplained is propagated as constant acceleration, like the slow case.
  double max_turn_rate_radps = 3.0;
  // The turn-rate noise uses min(|v_h|, this): bounded, like the jerk models', on a wild state.
  double max_noise_speed_mps = 40.0;

  // omega (rad/s); |v_h|^2 clamped to min_speed_mps^2 in the denominator, omega to
  // +-max_turn_rate_radps.
  double turn_rate(const StateVector& x) const;
  StateVector propagate(const StateVector& x, double dt_s) const;
  StateCovariance process_noise(const StateVector& x, double dt_s) const;
  // d propagate / d x at x, central differences.
  StateCovariance jacobian(const StateVector& x, double dt_s) const;
};

}  // namespace dronetrack::fusion
