#pragma once
// Processing parameters of an array node. Parsed and validated in config/ (parse_doa_params.cpp);
// every field has its unit in the name and a default that works on the bundled scenes.
#include <string>
#include <vector>

namespace dronetrack::doa {

struct FrequencyBand {
  double low_hz = 1500.0;
  double high_hz = 3500.0;
};

enum class TdoaTracker { per_frame, bayesian_grid, multi_peak, robust_regression };

struct DoaParams {
  std::vector<FrequencyBand> bands_hz{FrequencyBand{}};  // seed 002: 1.5-3.5 kHz
  double frame_s = 0.17;  // analysis frame length (rounded to a power of two samples? see doa/)
  double hop_s = 0.05;    // about 20 DOAs per second
  TdoaTracker tdoa_tracker = TdoaTracker::bayesian_grid;
  int max_sources = 2;            // DOAs per frame (SRP-PHAT peaks)
  double detection_snr_db = 6.0;  // in-band level over the adaptive noise floor to publish
};

}  // namespace dronetrack::doa
