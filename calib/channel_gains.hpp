#pragma once
// Channel gains from levels (issue 16). The pair delays say nothing of a channel's gain (GCC-PHAT
// divides every cross-spectrum by its magnitude), but the channels' levels do: during a flight
// every mic of an array hears the same sound to within the 1/r spreading across the array
// (0.3 dB at 20 m over a 0.8 m array, averaging out over a flight around it), so the level
// differences between channels are their gain differences.
#include <vector>

#include "calib/site_calibration.hpp"

namespace dronetrack::calib {

// `levels_db[k][i]`: channel i's level (dB, any reference) over stretch k of the flight.
// Returns per channel its gain relative to the channels' mean (they sum to 0): the median over
// the stretches of its level minus the stretch's mean level, std from the median absolute
// deviation / sqrt(stretches). Stretches with a channel below `floor_db` (silence, a dead
// channel) are left out; fewer than 3 left: an empty result.
std::vector<Estimate> estimate_channel_gains(const std::vector<std::vector<double>>& levels_db,
                                             double floor_db = -100.0);

}  // namespace dronetrack::calib
