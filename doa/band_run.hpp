#pragma once
// A run of consecutive FFT bins: the band is a short list of them (band_runs() in gcc_phat.hpp).

namespace dronetrack::doa {

struct BandRun {
  int first_bin = 0;  // inclusive
  int last_bin = 0;   // inclusive
};

}  // namespace dronetrack::doa
