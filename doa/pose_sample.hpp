#pragma once
// One line of a moving array's pose (issue 15): where the array's origin was and how it was
// turned at one time, on the recording's clock (pose_file) or the node's stream clock (the
// ArrayPose DDS topic). Attitude: yaw about +z (counter-clockwise from +x), then pitch about the
// new +y, then roll about the new +x (array_to_site = Rz(yaw) Ry(pitch) Rx(roll)), degrees.
#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace dronetrack::doa {

struct PoseSample {
  double time_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  // the array's origin, site frame
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
};

// Rz(yaw) Ry(pitch) Rx(roll), degrees: array frame to site frame.
inline Eigen::Quaterniond rotation_from_attitude_deg(double yaw_deg, double pitch_deg,
                                                     double roll_deg) {
  constexpr double kRadPerDeg = std::numbers::pi / 180.0;
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * kRadPerDeg, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(pitch_deg * kRadPerDeg, Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(roll_deg * kRadPerDeg, Eigen::Vector3d::UnitX()));
}

// (yaw, pitch, roll) in degrees of a rotation, the inverse of rotation_from_attitude_deg with
// pitch in [-90, 90] (yaw and roll in (-180, 180]).
inline Eigen::Vector3d attitude_deg_of(const Eigen::Quaterniond& array_to_site) {
  constexpr double kDegPerRad = 180.0 / std::numbers::pi;
  const Eigen::Matrix3d r = array_to_site.normalized().toRotationMatrix();
  const double pitch = std::asin(std::clamp(-r(2, 0), -1.0, 1.0));
  const double yaw = std::atan2(r(1, 0), r(0, 0));
  const double roll = std::atan2(r(2, 1), r(2, 2));
  return Eigen::Vector3d(yaw, pitch, roll) * kDegPerRad;
}

}  // namespace dronetrack::doa
