#include "sim/doa_outliers.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "doa/array_geometry.hpp"

namespace dronetrack::sim {

std::size_t add_doa_outliers(std::vector<doa::DoaMeasurement>& doas,
                             const DoaOutlierSettings& settings) {
  if (!(settings.share >= 0.0 && settings.share <= 1.0))
    throw std::invalid_argument("DOA outlier share must be in [0, 1]");
  Random random(settings.seed, stream_id(0x0D0A));
  std::size_t perturbed = 0;
  for (doa::DoaMeasurement& doa : doas) {
    // Always three draws per DOA, so the k-th DOA's fate does not depend on the ones before it.
    const bool outlier = random.uniform() < settings.share;
    const double azimuth_error_deg = draw_alpha_stable(settings.law_deg, random);
    const double elevation_error_deg = draw_alpha_stable(settings.law_deg, random);
    if (!outlier) continue;
    double azimuth = doa::azimuth_deg(doa.direction) + azimuth_error_deg;
    azimuth = std::remainder(azimuth, 360.0);
    const double elevation =
        std::clamp(doa::elevation_deg(doa.direction) + elevation_error_deg, -90.0, 90.0);
    if (!std::isfinite(azimuth)) continue;  // an error beyond 1e300 degrees: leave it be
    doa.direction = doa::direction_from_azel_deg(azimuth, elevation);
    ++perturbed;
  }
  return perturbed;
}

}  // namespace dronetrack::sim
