#include "sim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace dronetrack::sim {
namespace {

PathPiece line_piece(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  PathPiece piece;
  piece.start = from;
  piece.length_m = (to - from).norm();
  if (piece.length_m > 0.0) piece.direction = (to - from) / piece.length_m;
  return piece;
}

PathPiece arc_piece(const Eigen::Vector3d& start, const Eigen::Vector3d& direction,
                    const Eigen::Vector3d& normal, double radius_m, double angle_rad) {
  PathPiece piece;
  piece.is_arc = true;
  piece.start = start;
  piece.direction = direction;
  piece.normal = normal;
  piece.radius_m = radius_m;
  piece.centre = start + radius_m * normal;
  piece.length_m = radius_m * angle_rad;
  return piece;
}

// Position, unit tangent and curvature vector (d tangent / ds) at arc length `s` into `piece`
// (s may run past either end of a line piece: that is how open paths extend).
void evaluate(const PathPiece& piece, double s, Eigen::Vector3d& position, Eigen::Vector3d& tangent,
              Eigen::Vector3d& curvature) {
  if (!piece.is_arc) {
    position = piece.start + s * piece.direction;
    tangent = piece.direction;
    curvature.setZero();
    return;
  }
  const double angle = s / piece.radius_m;
  const double c = std::cos(angle);
  const double sn = std::sin(angle);
  position = piece.centre + piece.radius_m * (-c * piece.normal + sn * piece.direction);
  tangent = c * piece.direction + sn * piece.normal;
  curvature = (c * piece.normal - sn * piece.direction) / piece.radius_m;
}

}  // namespace

Trajectory Trajectory::fixed(const Eigen::Vector3d& position_m) {
  Trajectory trajectory;
  trajectory.origin_m_ = position_m;
  return trajectory;
}

Trajectory Trajectory::straight(const Eigen::Vector3d& start_m,
                                const Eigen::Vector3d& velocity_mps) {
  Trajectory trajectory;
  trajectory.origin_m_ = start_m;
  trajectory.velocity_mps_ = velocity_mps;
  return trajectory;
}

Trajectory Trajectory::circle(const Eigen::Vector3d& centre_m, double radius_m, double speed_mps,
                              double start_angle_deg, bool clockwise) {
  const double angle = start_angle_deg * std::numbers::pi / 180.0;
  const Eigen::Vector3d outward(std::cos(angle), std::sin(angle), 0.0);
  const Eigen::Vector3d counter_clockwise_tangent(-std::sin(angle), std::cos(angle), 0.0);
  Trajectory trajectory;
  trajectory.pieces_.push_back(
      arc_piece(centre_m + radius_m * outward,
                clockwise ? Eigen::Vector3d(-counter_clockwise_tangent) : counter_clockwise_tangent,
                -outward, radius_m, 2.0 * std::numbers::pi));
  trajectory.length_m_ = trajectory.pieces_.back().length_m;
  trajectory.speed_mps_ = speed_mps;
  trajectory.closed_ = true;
  return trajectory;
}

Trajectory Trajectory::through_points(const std::vector<Eigen::Vector3d>& points_m,
                                      double speed_mps, double turn_radius_m, bool closed) {
  Trajectory trajectory;
  trajectory.speed_mps_ = speed_mps;
  trajectory.closed_ = closed;
  const std::size_t count = points_m.size();
  const std::size_t legs = closed ? count : count - 1;
  auto leg_vector = [&](std::size_t leg) {
    return Eigen::Vector3d(points_m[(leg + 1) % count] - points_m[leg]);
  };
  // Corner i joins leg i-1 to leg i. Tangent length T = R tan(turn / 2), limited so that two
  // corners never claim more than a whole leg between them.
  struct Corner {
    bool rounded = false;
    Eigen::Vector3d arc_start, arc_end, incoming, normal;
    double radius_m = 0.0, angle_rad = 0.0;
  };
  std::vector<Corner> corners(count);
  for (std::size_t i = 0; i < count; ++i) {
    if (!closed && (i == 0 || i == count - 1)) continue;
    const Eigen::Vector3d before = leg_vector((i + count - 1) % count);
    const Eigen::Vector3d after = leg_vector(i);
    const Eigen::Vector3d incoming = before.normalized();
    const Eigen::Vector3d outgoing = after.normalized();
    const double angle = std::acos(std::clamp(incoming.dot(outgoing), -1.0, 1.0));
    if (angle < 1e-9 || angle > std::numbers::pi - 1e-6) continue;
    const double half_tan = std::tan(angle / 2.0);
    const double room_m = 0.5 * std::min(before.norm(), after.norm());
    const double radius_m = std::min(turn_radius_m, room_m / half_tan);
    if (radius_m <= 0.0) continue;
    Corner& corner = corners[i];
    corner.rounded = true;
    corner.radius_m = radius_m;
    corner.angle_rad = angle;
    corner.incoming = incoming;
    corner.normal = (outgoing - incoming.dot(outgoing) * incoming).normalized();
    corner.arc_start = points_m[i] - incoming * radius_m * half_tan;
    corner.arc_end = points_m[i] + outgoing * radius_m * half_tan;
  }
  auto leg_start = [&](std::size_t leg) {
    return corners[leg].rounded ? corners[leg].arc_end : points_m[leg];
  };
  auto leg_end = [&](std::size_t leg) {
    const std::size_t corner = (leg + 1) % count;
    return corners[corner].rounded ? corners[corner].arc_start : points_m[corner];
  };
  for (std::size_t leg = 0; leg < legs; ++leg) {
    trajectory.pieces_.push_back(line_piece(leg_start(leg), leg_end(leg)));
    const Corner& corner = corners[(leg + 1) % count];
    if (corner.rounded) {
      trajectory.pieces_.push_back(arc_piece(corner.arc_start, corner.incoming, corner.normal,
                                             corner.radius_m, corner.angle_rad));
    }
  }
  double s = 0.0;
  for (auto& piece : trajectory.pieces_) {
    piece.start_s_m = s;
    s += piece.length_m;
  }
  trajectory.length_m_ = s;
  return trajectory;
}

TrajectoryState Trajectory::at(double t_s) const {
  TrajectoryState state;
  if (pieces_.empty()) {
    state.position_m = origin_m_ + velocity_mps_ * t_s;
    state.velocity_mps = velocity_mps_;
    return state;
  }
  double s = start_offset_m_ + speed_mps_ * t_s;
  if (closed_ && length_m_ > 0.0) {
    s = std::fmod(s, length_m_);
    if (s < 0.0) s += length_m_;
  }
  // The last piece starting at or before s; open paths extend the first/last line.
  auto after = std::upper_bound(
      pieces_.begin(), pieces_.end(), s,
      [](double value, const PathPiece& piece) { return value < piece.start_s_m; });
  const PathPiece& piece = after == pieces_.begin() ? pieces_.front() : *(after - 1);
  Eigen::Vector3d tangent;
  Eigen::Vector3d curvature;
  evaluate(piece, s - piece.start_s_m, state.position_m, tangent, curvature);
  state.velocity_mps = speed_mps_ * tangent;
  state.acceleration_mps2 = speed_mps_ * speed_mps_ * curvature;
  return state;
}

}  // namespace dronetrack::sim
