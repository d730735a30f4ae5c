#pragma once
// The checks of one DOA that need no tracker state: finite values, a known array (its index
// trusted only when it agrees with its id), a unit direction (and ambiguity axis), a positive
// definite covariance or a cone angle in [0, pi] with a positive variance, a source index in
// [0, 64). The engine adds its own (too late, duplicate) and counts every verdict.
#include <cstdint>
#include <vector>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"

namespace dronetrack::fusion {

enum class DoaVerdict : std::uint8_t {
  accepted = 0,   // queued for the tracker
  non_finite,     // NaN/Inf in time, direction or covariance
  unknown_array,  // array id/index not in the site
  too_late,       // older than what the tracker has already processed
  duplicate,      // same array, same time, same source index as one already queued
  bad_direction,  // not a unit vector, or covariance not positive definite
};
const char* to_string(DoaVerdict verdict);

// accepted, non_finite, unknown_array or bad_direction; `index` gets the DOA's array's index in
// `arrays` when it is known.
DoaVerdict check_doa(const doa::DoaMeasurement& measurement,
                     const std::vector<doa::ArrayGeometry>& arrays, int& index);

}  // namespace dronetrack::fusion
