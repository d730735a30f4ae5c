#pragma once
// How a simulated array moves (issue 15): its origin follows a Trajectory (the same path types as
// sources) and its attitude is array_to_site = Rz(yaw) Ry(pitch) Rx(roll) (doa/pose_sample.hpp),
// with the yaw either fixed or following the heading of motion (a vehicle carrying a hydrophone
// pair). Pitch and roll are fixed. The pose lines the simulator writes come from pose().
#include <Eigen/Core>

#include "doa/pose_sample.hpp"
#include "sim/trajectory.hpp"

namespace dronetrack::sim {

// The yaw a platform may turn through between two pose lines; more and a reader could not
// tell which way it turned (doa::kMaxPoseYawStep_deg of the pose-file reader).
inline constexpr double kMaxPoseYawStep_deg = 45.0;

enum class YawMode {
  fixed,    // yaw = yaw_deg
  heading,  // yaw = direction of horizontal motion + yaw_deg (the mounting offset)
};

struct ArrayMotion {
  Trajectory trajectory;  // of the array's origin (position_m), site frame
  YawMode yaw_mode = YawMode::fixed;
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;

  // Yaw in (-180, 180] degrees at t.
  double yaw_at_deg(double t_s) const;
  // The pose line at t (time_s = t).
  doa::PoseSample pose(double t_s) const;
  // Site position and velocity of a point fixed in the array frame (a mic): the origin's motion
  // plus, while the yaw follows a turn, the rotation's omega x (R p).
  TrajectoryState point_state(const Eigen::Vector3d& array_point_m, double t_s) const;
};

}  // namespace dronetrack::sim
