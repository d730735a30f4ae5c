#pragma once
// One source has one spectrum at every array (issue 14's ghosts): two arrays hearing different
// spectra on one track are two sources whose rays cross, each heard by one of the arrays. Each
// array's DOAs a track took are tallied (AcousticTally); spectra_disagree() compares the arrays.
#include <span>

#include "doa/doa_measurement.hpp"

namespace dronetrack::fusion {

// What one array's DOAs taken by a track said of the source's spectrum.
struct AcousticTally {
  int analysed = 0;                 // DOAs with features
  int with_comb = 0;                // of those, with a harmonic comb (any fundamental)
  double fundamental_sum_hz = 0.0;  // over those with a comb
  void add(const doa::AcousticFeatures& features) {
    if (!features.valid) return;
    ++analysed;
    if (features.fundamental_hz > 0.0) {
      ++with_comb;
      fundamental_sum_hz += features.fundamental_hz;
    }
  }
};

// True when the arrays' tallies (each with at least min_analysed DOAs) cannot be one source: a
// comb at one array and none at another, or comb spacings further apart than the Doppler shift
// of a source at max_speed_mps explains (plus the detector's own spread). absence_counts false:
// the spacings alone. A comb's spacing is evidence from one analysis (the detector finds a
// drone's at its own spacing, never a multiple), its absence only from several (it finds a
// drone's comb in 55-97 % of analyses).
bool spectra_disagree(std::span<const AcousticTally> by_array, int min_analysed,
                      double max_speed_mps, double speed_of_sound_mps, bool absence_counts = true);

}  // namespace dronetrack::fusion
