#include "doa/carrier_fringe.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace dronetrack::doa {

double comb_carrier_hz(std::span<const double> power, std::span<const std::uint8_t> on_line,
                       int first_bin, double bin_hz) {
  double weight = 0.0;
  double weighted_bin = 0.0;
  const std::size_t bins = std::min(power.size(), on_line.size());
  for (std::size_t i = 0; i < bins; ++i) {
    if (on_line[i] == 0 || !(power[i] > 0.0)) continue;
    weight += power[i];
    weighted_bin += power[i] * static_cast<double>(first_bin + static_cast<int>(i));
  }
  return weight > 0.0 ? weighted_bin / weight * bin_hz : 0.0;
}

bool within_one_carrier_fringe(std::span<const double> lags_source_s,
                               std::span<const double> lags_other_s, double carrier_hz) {
  if (!(carrier_hz > 0.0)) return false;
  // Nearer the first neighbouring fringe than the second.
  const double limit_s = 1.5 / carrier_hz;
  int pairs = 0;
  const std::size_t count = std::min(lags_source_s.size(), lags_other_s.size());
  for (std::size_t p = 0; p < count; ++p) {
    if (!std::isfinite(lags_source_s[p]) || !std::isfinite(lags_other_s[p])) continue;
    if (std::abs(lags_other_s[p] - lags_source_s[p]) > limit_s) return false;
    ++pairs;
  }
  return pairs > 0;
}

bool comb_is_the_sources(const HarmonicComb& source, const HarmonicComb& other, int min_lines,
                         double spacing_tolerance_hz) {
  if (!other.found || other.harmonic_count < min_lines) return true;
  return source.found &&
         std::abs(other.fundamental_hz - source.fundamental_hz) <= spacing_tolerance_hz;
}

}  // namespace dronetrack::doa
