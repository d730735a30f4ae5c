#include "sim/array_motion.hpp"

#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "doa/array_geometry.hpp"

namespace dronetrack::sim {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

}  // namespace

double ArrayMotion::yaw_at_deg(double t_s) const {
  if (yaw_mode == YawMode::fixed) return doa::wrap_deg_180(yaw_deg);
  const Eigen::Vector3d velocity = trajectory.at(t_s).velocity_mps;
  return doa::wrap_deg_180(std::atan2(velocity.y(), velocity.x()) * kDegPerRad + yaw_deg);
}

doa::PoseSample ArrayMotion::pose(double t_s) const {
  doa::PoseSample sample;
  sample.time_s = t_s;
  sample.position_m = trajectory.position(t_s);
  sample.yaw_deg = yaw_at_deg(t_s);
  sample.pitch_deg = pitch_deg;
  sample.roll_deg = roll_deg;
  return sample;
}

TrajectoryState ArrayMotion::point_state(const Eigen::Vector3d& array_point_m, double t_s) const {
  const TrajectoryState origin = trajectory.at(t_s);
  double yaw_rate_rad_s = 0.0;
  double yaw = yaw_deg;
  if (yaw_mode == YawMode::heading) {
    const Eigen::Vector3d& v = origin.velocity_mps;
    const Eigen::Vector3d& a = origin.acceleration_mps2;
    const double horizontal_speed2 = v.x() * v.x() + v.y() * v.y();
    yaw += std::atan2(v.y(), v.x()) * kDegPerRad;
    if (horizontal_speed2 > 0.0)
      yaw_rate_rad_s = (v.x() * a.y() - v.y() * a.x()) / horizontal_speed2;
  }
  const Eigen::Vector3d offset = doa::attitude_to_site(yaw, pitch_deg, roll_deg) * array_point_m;
  TrajectoryState state;
  state.position_m = origin.position_m + offset;
  state.velocity_mps =
      origin.velocity_mps + yaw_rate_rad_s * Eigen::Vector3d::UnitZ().cross(offset);
  return state;
}

}  // namespace dronetrack::sim
