#pragma once
// DOA measurement model h(x), seen from one array's acoustic centre, of where the source was when
// the sound now arriving left it (SPEC 4.5). Built from the DOA's pose stamp alone (the array's
// fixed centre, or a moving array's centre at the frame's time), so adding an array is
// configuration (STYLE 3). What h returns depends on what the array can measure (SPEC 4.2):
//   azel           full direction: (azimuth, elevation) in radians
//   cone           two mics: (angle between the mic axis and the direction, 0): a 1-D measurement
//                  carried in the 2-vector with a zero second component (see state.hpp)
//   mirrored_azel  planar array: (azimuth, elevation) of the direction folded onto the side of
//                  the array plane the DOA reports (its mirror through the plane is as likely)
//
// Propagation delay: the DOA at time t points at p(t_e) with t_e + |p(t_e) - c| / speed = t. The
// state is at t, so t_e is found by a few fixed-point iterations that back-propagate the state
// with its own velocity and acceleration (0.9 s at 300 m: 9 m of flight at 10 m/s). For a moving
// array c is its centre at reception (the DOA's frame time): the sound arriving now left the
// source t - t_e ago wherever the array then was.
#include <cstdint>

#include <Eigen/Core>

#include "fusion/state.hpp"

namespace dronetrack::fusion {

enum class MeasurementKind : std::uint8_t { azel, cone, mirrored_azel };

struct DoaMeasurementModel {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();  // array acoustic centre, site frame
  double speed_of_sound_mps = 343.0;
  int delay_iterations = 3;  // 0: ignore the propagation delay
  MeasurementKind kind = MeasurementKind::azel;
  // cone: unit mic axis (mic 0 towards mic 1); mirrored_azel: unit normal of the array plane.
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  // mirrored_azel: the side of the plane the DOA reports, +1 (axis side) or -1.
  double mirror_side = 1.0;

  // Degrees of freedom of the measurement: 1 for a cone, else 2.
  int dimension() const { return kind == MeasurementKind::cone ? 1 : 2; }
  // Position at emission time and the delay (s) it took the sound to arrive.
  Eigen::Vector3d emission_position_m(const StateVector& x, double* delay_s = nullptr) const;
  Measurement predict(const StateVector& x) const;  // h(x)
  // h of a source seen along `to_source` (any length) from the centre, no delay.
  Measurement predict_direction(const Eigen::Vector3d& to_source) const;
  // z - z_hat: the azimuth wrapped for azel kinds, the cone angle plain (it lives in [0, pi]).
  Measurement residual(const Measurement& z, const Measurement& z_hat) const;
};

// (azimuth, elevation) in radians of a direction (need not be unit length).
Measurement azel_of(const Eigen::Vector3d& direction);
// z - z_hat with the azimuth wrapped to (-pi, pi]: the ONE place fusion wraps angles.
Measurement azel_residual(const Measurement& z, const Measurement& z_hat);
// (cone angle, 0) of a direction about a unit axis.
Measurement cone_of(const Eigen::Vector3d& direction, const Eigen::Vector3d& axis);

}  // namespace dronetrack::fusion
