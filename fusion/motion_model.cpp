#include "fusion/motion_model.hpp"

namespace dronetrack::fusion {

StateCovariance ConstantJerkModel::transition(double dt_s) const {
  const double t = dt_s;
  StateCovariance f = StateCovariance::Identity();
  for (int axis = 0; axis < 3; ++axis) {
    const int p = StateBlock::position + axis;
    const int v = StateBlock::velocity + axis;
    const int a = StateBlock::acceleration + axis;
    f(p, v) = t;
    f(p, a) = 0.5 * t * t;
    f(v, a) = t;
  }
  return f;
}

Eigen::Matrix<double, kStateSize, 3> ConstantJerkModel::noise_gain(double dt_s) const {
  const double t = dt_s;
  Eigen::Matrix<double, kStateSize, 3> gamma = Eigen::Matrix<double, kStateSize, 3>::Zero();
  for (int axis = 0; axis < 3; ++axis) {
    gamma(StateBlock::position + axis, axis) = t * t * t / 6.0;
    gamma(StateBlock::velocity + axis, axis) = 0.5 * t * t;
    gamma(StateBlock::acceleration + axis, axis) = t;
  }
  return gamma;
}

StateCovariance ConstantJerkModel::process_noise(double dt_s) const {
  const Eigen::Matrix<double, kStateSize, 3> gamma = noise_gain(dt_s);
  return jerk_variance_m2ps6 * gamma * gamma.transpose();
}

void ConstantJerkModel::predict(StateVector& x, StateCovariance& covariance, double dt_s) const {
  if (dt_s == 0.0) return;
  const StateCovariance f = transition(dt_s);
  x = f * x;
  covariance = f * covariance * f.transpose() + process_noise(dt_s);
  covariance = 0.5 * (covariance + covariance.transpose()).eval();
}

StateVector ConstantJerkModel::propagate(const StateVector& x, double dt_s) {
  StateVector out = x;
  const Eigen::Vector3d v = velocity_of(x);
  const Eigen::Vector3d a = acceleration_of(x);
  out.segment<3>(StateBlock::position) += v * dt_s + 0.5 * a * dt_s * dt_s;
  out.segment<3>(StateBlock::velocity) += a * dt_s;
  return out;
}

}  // namespace dronetrack::fusion
