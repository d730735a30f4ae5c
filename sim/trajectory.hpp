#pragma once
// Where a source is at any time t (seconds, any sign: sound arriving at t = 0 left before it).
// Paths are made of straight pieces and circular arcs travelled at constant speed, so position
// and velocity are continuous everywhere (turns are smooth); acceleration jumps where a line meets
// an arc, which bounds how well emission times can be interpolated (see propagation.hpp).
#include <cstddef>
#include <vector>

#include <Eigen/Core>

namespace dronetrack::sim {

struct PathPiece {
  // Line: start + direction * s. Arc: centre + radius * (-normal cos(s/R) + direction sin(s/R)),
  // i.e. it leaves `start` along `direction` and turns toward `normal`.
  bool is_arc = false;
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // unit tangent at the start
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();     // arcs: unit, toward the centre
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();      // arcs
  double radius_m = 0.0;                                 // arcs
  double length_m = 0.0;
  double start_s_m = 0.0;  // arc length at the start of this piece
};

struct TrajectoryState {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_mps = Eigen::Vector3d::Zero();
  // Zero on lines, centripetal on arcs (a platform whose yaw follows its heading turns at
  // (v x a).z / |v_xy|^2).
  Eigen::Vector3d acceleration_mps2 = Eigen::Vector3d::Zero();
};

class Trajectory {
 public:
  // A source that never moves.
  static Trajectory fixed(const Eigen::Vector3d& position_m);
  // Constant velocity through `start_m` at t = 0, for all t.
  static Trajectory straight(const Eigen::Vector3d& start_m, const Eigen::Vector3d& velocity_mps);
  // Through the points in order at `speed_mps`, corners rounded with arcs of `turn_radius_m`
  // (smaller where the legs are too short). Closed: back to the first point and round again,
  // starting at t = 0 on the first leg just after its corner. Open: starts at the first point
  // at t = 0 and continues in a straight line before the first and after the last point.
  static Trajectory through_points(const std::vector<Eigen::Vector3d>& points_m, double speed_mps,
                                   double turn_radius_m, bool closed);
  // A horizontal circle, counter-clockwise unless `clockwise`.
  static Trajectory circle(const Eigen::Vector3d& centre_m, double radius_m, double speed_mps,
                           double start_angle_deg, bool clockwise);

  TrajectoryState at(double t_s) const;
  Eigen::Vector3d position(double t_s) const { return at(t_s).position_m; }
  double path_length_m() const { return length_m_; }

 private:
  std::vector<PathPiece> pieces_;
  Eigen::Vector3d origin_m_ = Eigen::Vector3d::Zero();      // fixed / straight
  Eigen::Vector3d velocity_mps_ = Eigen::Vector3d::Zero();  // fixed / straight
  double speed_mps_ = 0.0;
  double length_m_ = 0.0;
  double start_offset_m_ = 0.0;  // arc length at t = 0
  bool closed_ = false;
};

}  // namespace dronetrack::sim
