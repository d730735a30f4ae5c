#pragma once
// The 9-state constant-jerk track state (SPEC 4.5, seed 002 eqs. 14-18), in the order TrackReport
// uses: [px py pz vx vy vz ax ay az]. Blocks are named so no code indexes a bare number.
#include <Eigen/Core>

namespace dronetrack::fusion {

inline constexpr int kStateSize = 9;
inline constexpr int kMeasurementSize = 2;  // (azimuth, elevation), radians

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

}  // namespace dronetrack::fusion
