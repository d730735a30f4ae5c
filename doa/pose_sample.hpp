#pragma once
// One line of a moving array's pose (issue 15): where the array's origin was and how it was
// turned at one time, on the recording's clock (pose_file) or the node's stream clock (the
// ArrayPose DDS topic). Attitude: yaw about +z (counter-clockwise from +x), then pitch about the
// new +y, then roll about the new +x (array_to_site = Rz(yaw) Ry(pitch) Rx(roll)), degrees.
#include <Eigen/Core>

namespace dronetrack::doa {

struct PoseSample {
  double time_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  // the array's origin, site frame
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
};

}  // namespace dronetrack::doa
