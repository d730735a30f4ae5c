#pragma once
// Test scenes from physics: array geometries, known trajectories, and the DOAs an ideal array
// would report for them, including the propagation delay (the direction at reception time t
// points to where the drone was at t_e with t_e + |p(t_e) - c| / speed = t).
#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"

namespace dronetrack::fusion::testing {

inline doa::ArrayGeometry tetrahedron(const std::string& id, const Eigen::Vector3d& position_m) {
  doa::ArrayGeometry array;
  array.id = id;
  array.position_m = position_m;
  array.mics_m = {
      {0, 0, 0.5}, {0.4714, 0, -0.1667}, {-0.2357, 0.4082, -0.1667}, {-0.2357, -0.4082, -0.1667}};
  return array;
}

using Trajectory = std::function<Eigen::Vector3d(double)>;

// Emission time of the sound reaching `centre` at `time_s` (bisection: exact to 1e-9 s).
inline double emission_time_s(const Trajectory& path, const Eigen::Vector3d& centre, double time_s,
                              double speed_mps) {
  double low = time_s - 10.0;
  double high = time_s;
  for (int i = 0; i < 80; ++i) {
    const double middle = 0.5 * (low + high);
    const double arrival = middle + (path(middle) - centre).norm() / speed_mps;
    (arrival > time_s ? high : low) = middle;
  }
  return 0.5 * (low + high);
}

struct DoaNoise {
  double std_deg = 0.0;
  bool with_delay = true;
};

inline doa::DoaMeasurement ideal_doa(const Trajectory& path, const doa::ArrayGeometry& array,
                                     int array_index, double time_s, double speed_mps,
                                     const DoaNoise& noise, std::mt19937_64& random) {
  const Eigen::Vector3d centre = array.centre_site_m();
  const double emitted =
      noise.with_delay ? emission_time_s(path, centre, time_s, speed_mps) : time_s;
  const Eigen::Vector3d direction = (path(emitted) - centre).normalized();
  std::normal_distribution<double> normal(0.0, 1.0);
  const double az =
      std::atan2(direction.y(), direction.x()) + normal(random) * noise.std_deg * M_PI / 180.0;
  const double el = std::asin(direction.z()) + normal(random) * noise.std_deg * M_PI / 180.0;
  doa::DoaMeasurement m;
  m.array_id = array.id;
  m.array_index = array_index;
  m.time_s = time_s;
  m.direction = doa::direction_from_azel_deg(az * 180.0 / M_PI, el * 180.0 / M_PI);
  const double variance = std::pow(std::max(noise.std_deg, 0.05) * M_PI / 180.0, 2);
  m.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * variance;
  m.quality = 1.0;
  return m;
}

}  // namespace dronetrack::fusion::testing
