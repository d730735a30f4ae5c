#include "fusion/doa_admission.hpp"

#include <cmath>
#include <numbers>

#include "fusion/state.hpp"

namespace dronetrack::fusion {

namespace {
constexpr double kUnitTolerance = 1e-3;
}  // namespace

const char* to_string(DoaVerdict verdict) {
  switch (verdict) {
    case DoaVerdict::accepted:
      return "accepted";
    case DoaVerdict::non_finite:
      return "non_finite";
    case DoaVerdict::unknown_array:
      return "unknown_array";
    case DoaVerdict::too_late:
      return "too_late";
    case DoaVerdict::duplicate:
      return "duplicate";
    case DoaVerdict::bad_direction:
      return "bad_direction";
  }
  return "unknown";
}

DoaVerdict check_doa(const doa::DoaMeasurement& measurement,
                     const std::vector<doa::ArrayGeometry>& arrays, int& index) {
  const bool cone = measurement.ambiguity == doa::DoaAmbiguity::cone;
  if (!std::isfinite(measurement.time_s) || !measurement.direction.allFinite() ||
      (!cone && !measurement.azel_covariance_rad2.allFinite()) ||
      (measurement.pose.moving && !measurement.pose.centre_m.allFinite()) ||
      (measurement.ambiguity != doa::DoaAmbiguity::none &&
       !measurement.ambiguity_axis.allFinite()) ||
      (cone && !(std::isfinite(measurement.cone_angle_rad) &&
                 std::isfinite(measurement.cone_angle_variance_rad2)))) {
    return DoaVerdict::non_finite;
  }
  // The index is trusted only when it agrees with the id (or the id is absent).
  index = measurement.array_index;
  const auto count = static_cast<int>(arrays.size());
  const bool index_ok = index >= 0 && index < count &&
                        (measurement.array_id.empty() || arrays[index].id == measurement.array_id);
  if (!index_ok) {
    index = -1;
    for (int i = 0; i < count; ++i) {
      if (!measurement.array_id.empty() && arrays[i].id == measurement.array_id) index = i;
    }
    if (index < 0) return DoaVerdict::unknown_array;
  }
  if (std::abs(measurement.direction.norm() - 1.0) > kUnitTolerance) {
    return DoaVerdict::bad_direction;
  }
  if (measurement.ambiguity != doa::DoaAmbiguity::none &&
      std::abs(measurement.ambiguity_axis.norm() - 1.0) > kUnitTolerance) {
    return DoaVerdict::bad_direction;
  }
  if (cone) {
    // The cone is the measurement (its display direction is not): an angle in [0, pi] with a
    // positive variance.
    if (!(measurement.cone_angle_rad >= 0.0 && measurement.cone_angle_rad <= std::numbers::pi) ||
        !(measurement.cone_angle_variance_rad2 > 0.0)) {
      return DoaVerdict::bad_direction;
    }
  } else {
    const MeasurementCovariance& r = measurement.azel_covariance_rad2;
    if (!(r(0, 0) > 0.0) || !(r.determinant() > 0.0) ||
        std::abs(r(0, 1) - r(1, 0)) > 1e-12 * r.norm()) {
      return DoaVerdict::bad_direction;
    }
  }
  if (measurement.source_index < 0 || measurement.source_index >= 64) {
    return DoaVerdict::bad_direction;
  }
  return DoaVerdict::accepted;
}

}  // namespace dronetrack::fusion
