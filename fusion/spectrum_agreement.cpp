#include "fusion/spectrum_agreement.hpp"

#include <algorithm>
#include <limits>

namespace dronetrack::fusion {

bool spectra_disagree(std::span<const AcousticTally> by_array, int min_analysed,
                      double max_speed_mps, double speed_of_sound_mps, bool absence_counts) {
  // Only an array that gave the track enough analysed DOAs to say what it hears: a comb in most
  // of them, or in few. A comb found now and then (a weak source near the detector's floor)
  // says neither.
  constexpr double kCombShare = 0.75;
  constexpr double kNoCombShare = 0.25;
  // Two arrays hear one source's comb spacing shifted by its Doppler towards each, at most
  // 2 v / c apart, plus the detector's own spread (a few %). The detector takes the smallest
  // spacing that correlates nearly as well as the best, so it does not report a multiple.
  const double tolerance = 2.0 * max_speed_mps / speed_of_sound_mps + 0.05;
  bool comb_heard = false;
  bool no_comb_heard = false;
  double lowest_hz = std::numeric_limits<double>::infinity();
  double highest_hz = 0.0;
  for (const AcousticTally& tally : by_array) {
    if (tally.analysed < min_analysed) continue;
    const double share = static_cast<double>(tally.with_comb) / tally.analysed;
    if (share <= kNoCombShare) no_comb_heard = true;
    if (share < kCombShare) continue;
    comb_heard = true;
    const double fundamental_hz = tally.fundamental_sum_hz / tally.with_comb;
    lowest_hz = std::min(lowest_hz, fundamental_hz);
    highest_hz = std::max(highest_hz, fundamental_hz);
  }
  if (absence_counts && comb_heard && no_comb_heard) return true;
  return highest_hz > lowest_hz * (1.0 + tolerance);
}

}  // namespace dronetrack::fusion
