#pragma once
// DOA measurement model h(x): the (azimuth, elevation) in radians, seen from one array's acoustic
// centre, of where the drone was when the sound now arriving left it (SPEC 4.5). Built from the
// array pose alone, so adding an array is configuration (STYLE 3).
//
// Propagation delay: the DOA at time t points at p(t_e) with t_e + |p(t_e) - c| / speed = t. The
// state is at t, so t_e is found by a few fixed-point iterations that back-propagate the state
// with its own velocity and acceleration (0.9 s at 300 m: 9 m of flight at 10 m/s).
#include <Eigen/Core>

#include "fusion/state.hpp"

namespace dronetrack::fusion {

struct DoaMeasurementModel {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();  // array acoustic centre, site frame
  double speed_of_sound_mps = 343.0;
  int delay_iterations = 3;  // 0: ignore the propagation delay

  // Position at emission time and the delay (s) it took the sound to arrive.
  Eigen::Vector3d emission_position_m(const StateVector& x, double* delay_s = nullptr) const;
  Measurement predict(const StateVector& x) const;  // h(x)
};

// (azimuth, elevation) in radians of a direction (need not be unit length).
Measurement azel_of(const Eigen::Vector3d& direction);
// z - z_hat with the azimuth wrapped to (-pi, pi]: the ONE place fusion wraps angles.
Measurement azel_residual(const Measurement& z, const Measurement& z_hat);

}  // namespace dronetrack::fusion
