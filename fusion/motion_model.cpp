#include "fusion/motion_model.hpp"

#include <algorithm>
#include <cmath>

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

namespace {

// Below this |omega T| the arc coefficients come from their Taylor series (first omitted term
// ~ theta^6 / 5040 relative).
constexpr double kSmallTurnAngleRad = 1e-2;

// Integrals of the rotation over [0, T] at rate omega:
//   S = int cos(omega s) ds,  C = int sin(omega s) ds,
//   Ss = int s cos(omega s) ds,  Cs = int s sin(omega s) ds.
struct ArcIntegrals {
  double s = 0.0;
  double c = 0.0;
  double ss = 0.0;
  double cs = 0.0;
};

ArcIntegrals arc_integrals(double omega, double t) {
  const double theta = omega * t;
  ArcIntegrals out;
  if (std::abs(theta) < kSmallTurnAngleRad) {
    const double q = theta * theta;
    out.s = t * (1.0 - q / 6.0 + q * q / 120.0);
    out.c = t * theta * (0.5 - q / 24.0 + q * q / 720.0);
    out.ss = t * t * (0.5 - q / 8.0 + q * q / 144.0);
    out.cs = t * t * theta * (1.0 / 3.0 - q / 30.0 + q * q / 840.0);
    return out;
  }
  const double sin_theta = std::sin(theta);
  const double cos_theta = std::cos(theta);
  out.s = sin_theta / omega;
  out.c = (1.0 - cos_theta) / omega;
  out.ss = t * sin_theta / omega + (cos_theta - 1.0) / (omega * omega);
  out.cs = sin_theta / (omega * omega) - t * cos_theta / omega;
  return out;
}

// [[x, -y], [y, x]] applied to v: the rotation-integral matrices all have this form.
Eigen::Vector2d rotate_scale(double x, double y, const Eigen::Vector2d& v) {
  return {x * v.x() - y * v.y(), y * v.x() + x * v.y()};
}

Eigen::Vector2d perpendicular(const Eigen::Vector2d& v) { return {-v.y(), v.x()}; }  // J v

}  // namespace

double CoordinatedTurnModel::turn_rate(const StateVector& x) const {
  const Eigen::Vector2d v = x.segment<2>(StateBlock::velocity);
  const Eigen::Vector2d a = x.segment<2>(StateBlock::acceleration);
  const double scale = std::max(v.squaredNorm(), min_speed_mps * min_speed_mps);
  if (!(scale > 0.0)) return 0.0;
  return std::clamp((v.x() * a.y() - v.y() * a.x()) / scale, -max_turn_rate_radps,
                    max_turn_rate_radps);
}

StateVector CoordinatedTurnModel::propagate(const StateVector& x, double dt_s) const {
  const double t = dt_s;
  const Eigen::Vector2d v = x.segment<2>(StateBlock::velocity);
  const Eigen::Vector2d a = x.segment<2>(StateBlock::acceleration);
  const double scale = std::max(v.squaredNorm(), min_speed_mps * min_speed_mps);
  if (!(scale > 0.0)) return ConstantJerkModel::propagate(x, dt_s);
  // a_h = alpha v_h + omega J v_h + rest: turn rate, relative tangential acceleration, and the
  // part that neither explains (zero at speed >= min_speed_mps, all of a_h when hovering).
  const double omega = turn_rate(x);
  const double alpha = v.dot(a) / scale;
  const Eigen::Vector2d rest = a - alpha * v - omega * perpendicular(v);
  const ArcIntegrals arc = arc_integrals(omega, t);
  const double cos_theta = std::cos(omega * t);
  const double sin_theta = std::sin(omega * t);
  // v_h(s) = R(omega s) (1 + alpha s) v_h + rest s: the speed changes at a constant rate along
  // the turning heading (exact circle when alpha = 0, constant acceleration when omega = 0).
  StateVector out = x;
  out.segment<2>(StateBlock::position) +=
      rotate_scale(arc.s, arc.c, v) + alpha * rotate_scale(arc.ss, arc.cs, v) + 0.5 * t * t * rest;
  out.segment<2>(StateBlock::velocity) =
      rotate_scale(cos_theta, sin_theta, (1.0 + alpha * t) * v) + t * rest;
  out.segment<2>(StateBlock::acceleration) =
      rotate_scale(cos_theta, sin_theta, a - rest + omega * alpha * t * perpendicular(v)) + rest;
  // Vertical: constant acceleration.
  const double vz = x(StateBlock::velocity + 2);
  const double az = x(StateBlock::acceleration + 2);
  out(StateBlock::position + 2) += vz * t + 0.5 * az * t * t;
  out(StateBlock::velocity + 2) += az * t;
  return out;
}

StateCovariance CoordinatedTurnModel::process_noise(const StateVector& x, double dt_s) const {
  const double t = dt_s;
  const Eigen::Vector3d gain(t * t * t / 6.0, 0.5 * t * t, t);  // Gamma per axis
  StateCovariance q = StateCovariance::Zero();
  for (int axis = 0; axis < 3; ++axis) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        q(3 * i + axis, 3 * j + axis) = jerk_variance_m2ps6 * gain(i) * gain(j);
    }
  }
  // Normal jerk omega' |v_h| along n / |n|, n = (-v_y, v_x, 0), |v_h| capped.
  Eigen::Vector2d normal(-x(StateBlock::velocity + 1), x(StateBlock::velocity));
  // Capped: a diverging state (wild DOAs forced in) must not feed its own speed back into Q.
  const double speed = normal.norm();
  if (speed > max_noise_speed_mps) normal *= max_noise_speed_mps / speed;
  Eigen::Matrix<double, kStateSize, 1> g = Eigen::Matrix<double, kStateSize, 1>::Zero();
  for (int i = 0; i < 3; ++i) g.segment<2>(3 * i) = gain(i) * normal;
  q += turn_rate_variance_rad2ps4 * g * g.transpose();
  return q;
}

StateCovariance CoordinatedTurnModel::jacobian(const StateVector& x, double dt_s) const {
  return central_difference_jacobian<kStateSize>(
      x, [&](const StateVector& state) { return propagate(state, dt_s); },
      [](const StateVector& a, const StateVector& b) { return StateVector(a - b); });
}

}  // namespace dronetrack::fusion
