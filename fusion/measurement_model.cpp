#include "fusion/measurement_model.hpp"

#include <algorithm>
#include <cmath>

#include "doa/array_geometry.hpp"
#include "fusion/motion_model.hpp"

namespace dronetrack::fusion {

Eigen::Vector3d DoaMeasurementModel::emission_position_m(const StateVector& x,
                                                         double* delay_s) const {
  const Eigen::Vector3d position = position_of(x);
  double delay = 0.0;
  Eigen::Vector3d emitted = position;
  for (int iteration = 0; iteration < delay_iterations; ++iteration) {
    // Contraction with factor |v|/c (< 0.1 for drones): three steps reach millimetres.
    delay = (emitted - centre_m).norm() / speed_of_sound_mps;
    emitted = position_of(ConstantJerkModel::propagate(x, -delay));
  }
  if (delay_s != nullptr) *delay_s = delay;
  return emitted;
}

Measurement DoaMeasurementModel::predict(const StateVector& x) const {
  return azel_of(emission_position_m(x) - centre_m);
}

Measurement azel_of(const Eigen::Vector3d& direction) {
  const double horizontal = std::hypot(direction.x(), direction.y());
  return {std::atan2(direction.y(), direction.x()), std::atan2(direction.z(), horizontal)};
}

Measurement azel_residual(const Measurement& z, const Measurement& z_hat) {
  return {doa::wrap_rad_pi(z(0) - z_hat(0)), z(1) - z_hat(1)};
}

}  // namespace dronetrack::fusion
