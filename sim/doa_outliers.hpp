#pragma once
// Impulsive DOA errors for fusion-only experiments (issue 17): `replay --doa-in D.jsonl
// --doa-outliers SHARE` perturbs a known share of recorded DOAs by alpha-stable angular errors, so
// the filters can be compared on the drone problem with a known outlier share. The DOAs' stated
// standard deviations are left as they were: the filter is not told which ones are outliers.
#include <cstdint>
#include <vector>

#include "doa/doa_measurement.hpp"
#include "sim/alpha_stable.hpp"

namespace dronetrack::sim {

struct DoaOutlierSettings {
  double share = 0.0;  // probability that a DOA is an outlier, [0, 1]
  // Angular error law in degrees, drawn independently for azimuth and elevation. The default is a
  // symmetric heavy tail of a few degrees: a reflection or a second source captured for a frame.
  AlphaStable law_deg{1.5, 0.0, 5.0, 0.0};
  std::uint64_t seed = 1;
};

// Perturbs each DOA with probability `share` (deterministic for a seed and the DOAs' order);
// returns how many were perturbed. Elevation is kept within +-90 deg, azimuth wrapped.
std::size_t add_doa_outliers(std::vector<doa::DoaMeasurement>& doas,
                             const DoaOutlierSettings& settings);

}  // namespace dronetrack::sim
