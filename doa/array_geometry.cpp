#include "doa/array_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace dronetrack::doa {
namespace {
constexpr double kDegPerRad = 180.0 / std::numbers::pi;
}

Eigen::Matrix3d attitude_to_site(double yaw_deg, double pitch_deg, double roll_deg) {
  return (Eigen::AngleAxisd(yaw_deg / kDegPerRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_deg / kDegPerRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_deg / kDegPerRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d attitude_deg_of(const Eigen::Quaterniond& array_to_site) {
  const Eigen::Matrix3d r = array_to_site.normalized().toRotationMatrix();
  const double pitch = std::asin(std::clamp(-r(2, 0), -1.0, 1.0));
  const double yaw = std::atan2(r(1, 0), r(0, 0));
  const double roll = std::atan2(r(2, 1), r(2, 2));
  return Eigen::Vector3d(yaw, pitch, roll) * kDegPerRad;
}

Eigen::Matrix3d ArrayGeometry::array_to_site() const {
  return attitude_to_site(yaw_deg, pitch_deg, roll_deg);
}

Eigen::Vector3d ArrayGeometry::mic_site_m(std::size_t mic) const {
  return position_m + array_to_site() * mics_m.at(mic);
}

Eigen::Vector3d ArrayGeometry::centre_site_m() const {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& mic : mics_m) centroid += mic;
  if (!mics_m.empty()) centroid /= static_cast<double>(mics_m.size());
  return position_m + array_to_site() * centroid;
}

double azimuth_deg(const Eigen::Vector3d& u) { return std::atan2(u.y(), u.x()) * kDegPerRad; }

double elevation_deg(const Eigen::Vector3d& u) {
  const double norm = u.norm();
  if (!(norm > 0.0)) return 0.0;
  return std::asin(std::clamp(u.z() / norm, -1.0, 1.0)) * kDegPerRad;
}

Eigen::Vector3d direction_from_azel_deg(double az_deg, double el_deg) {
  const double az = az_deg / kDegPerRad;
  const double el = el_deg / kDegPerRad;
  return {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
}

double wrap_deg_180(double angle_deg) {
  double wrapped = std::remainder(angle_deg, 360.0);  // [-180, 180]
  if (wrapped <= -180.0) wrapped += 360.0;
  return wrapped;
}

double wrap_rad_pi(double angle_rad) {
  double wrapped = std::remainder(angle_rad, 2.0 * std::numbers::pi);
  if (wrapped <= -std::numbers::pi) wrapped += 2.0 * std::numbers::pi;
  return wrapped;
}

double angle_between_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  // atan2 of cross and dot stays accurate for tiny angles, where acos(dot) does not.
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kDegPerRad;
}

}  // namespace dronetrack::doa
