#pragma once
// The 9-state constant-jerk track state (SPEC 4.5, seed 002 eqs. 14-18), in the order TrackReport
// uses: [px py pz vx vy vz ax ay az]. Blocks are named so no code indexes a bare number.
#include <cmath>

#include <Eigen/Core>

namespace dronetrack::fusion {

inline constexpr int kStateSize = 9;
// The largest measurement: (azimuth, elevation), radians. A 1-D measurement (a two-mic array's cone
// angle) rides in the same fixed-size vector with 0 as its second component in z, in h(x) and in
// every residual, and unit variance in that slot of R: its row of H is zero, so it adds nothing to
// the gain, 0 to d^2 and ln 1 = 0 to ln det S. Gates and costs take the true dimension from the
// model (DoaMeasurementModel::dimension). Fixed size keeps the per-measurement path free of
// allocation and every existing 2-D path unchanged.
inline constexpr int kMeasurementSize = 2;

using StateVector = Eigen::Matrix<double, kStateSize, 1>;
using StateCovariance = Eigen::Matrix<double, kStateSize, kStateSize>;
using Measurement = Eigen::Matrix<double, kMeasurementSize, 1>;
using MeasurementCovariance = Eigen::Matrix<double, kMeasurementSize, kMeasurementSize>;
using CrossCovariance = Eigen::Matrix<double, kStateSize, kMeasurementSize>;

// Offsets of the 3-vector blocks inside StateVector.
struct StateBlock {
  static constexpr int position = 0;
  static constexpr int velocity = 3;
  static constexpr int acceleration = 6;
};

inline Eigen::Vector3d position_of(const StateVector& x) {
  return x.segment<3>(StateBlock::position);
}
inline Eigen::Vector3d velocity_of(const StateVector& x) {
  return x.segment<3>(StateBlock::velocity);
}
inline Eigen::Vector3d acceleration_of(const StateVector& x) {
  return x.segment<3>(StateBlock::acceleration);
}

// Jacobian of f at x by central differences (step 1e-5 (1 + |x_i|) per state), for the EKF's
// measurement model and the turn model's transition. `difference(a, b)` is a - b in f's space
// (wrapped for angles).
template <int Rows, class Function, class Difference>
Eigen::Matrix<double, Rows, kStateSize> central_difference_jacobian(const StateVector& x,
                                                                    Function&& f,
                                                                    Difference&& difference) {
  Eigen::Matrix<double, Rows, kStateSize> jacobian;
  for (int i = 0; i < kStateSize; ++i) {
    const double step = 1e-5 * (1.0 + std::abs(x(i)));
    StateVector plus = x;
    StateVector minus = x;
    plus(i) += step;
    minus(i) -= step;
    jacobian.col(i) = difference(f(plus), f(minus)) / (2.0 * step);
  }
  return jacobian;
}

}  // namespace dronetrack::fusion
