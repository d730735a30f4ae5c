#pragma once
// What one DOA alone says about where its source is, before any range is known (issue 15; seeds
// 000, 003, 004), and the priors the one-array localisers start from.
//
// The locus: the points at range r from the array centre that fit the DOA exactly, one per
// branch:
//   azel           the ray (one branch)
//   mirrored_azel  the ray and its mirror image through the array plane (two)
//   cone           nothing without a source plane (a cone is a surface: range and one angle
//                  unknown); with one, where the cone cuts it: |d| = r, d_z = h, axis . d = r cos
//                  theta, two points d0 +- t n with n the horizontal normal to the axis (two
//                  branches, one each side of the axis: seed 003's front/back ambiguity)
// With a source plane, the azel kinds keep the azimuth and take their height from the plane (the
// papers' 2-D problem), so every branch is a curve on the plane.
#include <array>
#include <limits>
#include <optional>

#include <Eigen/Core>

#include "fusion/fusion_params.hpp"
#include "fusion/measurement_model.hpp"
#include "fusion/state.hpp"

namespace dronetrack::fusion {

struct BearingLocus {
  DoaMeasurementModel model;            // of the DOA that started it
  Measurement z = Measurement::Zero();  // what it measured
  double angle_std_rad = 0.01;          // its angular std (incl. the noise floor)
  Eigen::Vector3d hint_direction = Eigen::Vector3d::UnitX();  // the node's display direction
  std::optional<double> source_plane_z_m;
  // No source under the ground: points below this site height are not on the locus.
  double min_altitude_m = -std::numeric_limits<double>::infinity();
  int branch_count = 0;
  // Offset from the centre of the branch's point at range_m, if the branch reaches that range
  // above min_altitude_m.
  std::optional<Eigen::Vector3d> offset_at(int branch, double range_m) const;
  // The same, ignoring the ground.
  std::optional<Eigen::Vector3d> offset_anywhere(int branch, double range_m) const;
  // The branch whose point at range_m is nearest the hint (seed 000's EKF takes one side).
  int preferred_branch(double range_m) const;
};

// Empty when the DOA alone cannot start a track (a cone without a plane, or about a vertical axis:
// its cut with a horizontal plane is a circle).
std::optional<BearingLocus> bearing_locus(const DoaMeasurementModel& model, const Measurement& z,
                                          double angle_std_rad,
                                          const Eigen::Vector3d& hint_direction,
                                          std::optional<double> source_plane_z_m);

// Seed 000 eq. 16: covariance of a point at `offset` (range r = |offset|) from a range std and an
// angle std, P = sigma_r^2 u u^T + (r sigma_theta)^2 (I - u u^T), u = offset / r (the Jacobian of
// eq. 15 applied to diag(sigma_r^2, sigma_theta^2), in 3-D).
Eigen::Matrix3d range_bearing_covariance(const Eigen::Vector3d& offset, double range_std_m,
                                         double angle_std_rad);

// A state at rest at `position` with the prior's velocity and acceleration spread.
void state_at(const Eigen::Vector3d& position, const Eigen::Matrix3d& position_covariance,
              const OneArrayParams& params, StateVector& mean, StateCovariance& covariance);

// The source-plane pseudo-measurement: z = plane, v_z = a_z = 0 (std plane_std_m, and that per
// second and per second squared), a Kalman update of the vertical states. Returns false (and
// leaves the state) if the result is not finite.
bool constrain_to_plane(StateVector& mean, StateCovariance& covariance, double plane_z_m,
                        double plane_std_m);

}  // namespace dronetrack::fusion
