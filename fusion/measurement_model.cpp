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
  return predict_direction(emission_position_m(x) - centre_m);
}

Measurement DoaMeasurementModel::predict_direction(const Eigen::Vector3d& to_source) const {
  switch (kind) {
    case MeasurementKind::azel:
      return azel_of(to_source);
    case MeasurementKind::cone:
      return cone_of(to_source, axis);
    case MeasurementKind::mirrored_azel: {
      const double along = to_source.dot(axis);
      // Fold onto the reported side: the array cannot tell a direction from its mirror image.
      return azel_of(along * mirror_side < 0.0 ? Eigen::Vector3d(to_source - 2.0 * along * axis)
                                               : to_source);
    }
  }
  return azel_of(to_source);
}

Measurement DoaMeasurementModel::residual(const Measurement& z, const Measurement& z_hat) const {
  if (kind == MeasurementKind::cone) return {z(0) - z_hat(0), 0.0};
  return azel_residual(z, z_hat);
}

Measurement azel_of(const Eigen::Vector3d& direction) {
  const double horizontal = std::hypot(direction.x(), direction.y());
  return {std::atan2(direction.y(), direction.x()), std::atan2(direction.z(), horizontal)};
}

Measurement azel_residual(const Measurement& z, const Measurement& z_hat) {
  return {doa::wrap_rad_pi(z(0) - z_hat(0)), z(1) - z_hat(1)};
}

Measurement cone_of(const Eigen::Vector3d& direction, const Eigen::Vector3d& axis) {
  // atan2 of (|a x d|, a . d): accurate at endfire, where acos of the dot product loses digits.
  return {std::atan2(axis.cross(direction).norm(), axis.dot(direction)), 0.0};
}

}  // namespace dronetrack::fusion
