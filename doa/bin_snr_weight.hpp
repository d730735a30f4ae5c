#pragma once
// Per-bin SNR weight for GCC-PHAT. PHAT gives every band bin the same weight, which is right
// when every bin is well above the noise (seed 002 at 10 dB) and wasteful when the source's power
// sits in a few bins: a rotor's harmonics at 0 dB in-band SNR leave most bins pure noise, each
// adding its random phase to the correlation. Weighting each bin by its Wiener gain
// xi / (1 + xi) (xi: the bin's a-priori SNR; Valin et al. 2007, "Robust localization and tracking
// of simultaneous moving sound sources") keeps PHAT's whitening where the source is and fades the
// rest. The noise per bin is followed by minimum tracking of the smoothed power (averaged over
// the array's mics): it falls at once to a quieter bin and rises slowly, so a drone that stays in
// view is not learned as noise while its harmonics wander across bins.
#include <span>
#include <vector>

#include "doa/gcc_phat.hpp"
#include "doa/spectral_frame.hpp"

namespace dronetrack::doa {

class BinSnrWeight {
 public:
  // `runs`: the band's bins (GccPhat::band()); `hop_s`: time between updates;
  // `noise_rise_db_per_s`: how fast a bin's noise estimate may follow a louder background.
  BinSnrWeight(std::vector<BandRun> runs, double hop_s, double noise_rise_db_per_s, double floor);

  // One frame's |X|^2 of each channel over the band bins in (channel c's row at c * band bins;
  // GccPhat::band_powers(), so no pass over the spectra of its own), one weight in [0, 1] per
  // band bin out (GccPhat order). Non-finite powers leave the estimates alone and give weight 1
  // (plain PHAT).
  void update(std::span<const double> channel_powers, int channels, std::span<double> weights);

 private:
  // The update from power_ (this frame's mean power per band bin).
  void weigh(std::span<double> weights);

  std::vector<BandRun> runs_;
  int band_bins_ = 0;
  double floor_ = 0.0;
  double rise_per_update_ = 1.0;  // noise estimate may grow by this factor per frame
  bool started_ = false;
  std::vector<double> power_;     // this frame's power per band bin, mean over mics
  std::vector<double> smoothed_;  // recursive average of power_
  std::vector<double> noise_;     // minimum-tracked smoothed_
};

}  // namespace dronetrack::doa
