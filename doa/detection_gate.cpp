#include "doa/detection_gate.hpp"

#include <algorithm>
#include <cmath>

namespace dronetrack::doa {

namespace {
double to_db(double power) { return 10.0 * std::log10(std::max(power, 1e-30)); }
}  // namespace

DetectionGate::DetectionGate(const DetectionSettings& settings, double hop_s)
    : settings_(settings), max_rise_db_per_frame_(settings.floor_rise_db_per_s * hop_s) {}

bool DetectionGate::update(const DetectionInput& input) {
  const double power = std::isfinite(input.inband_power) ? input.inband_power : 0.0;
  level_dbfs_ = to_db(power);
  detecting_ = false;
  if (level_dbfs_ < settings_.silence_dbfs || !input.frame_clean) {
    snr_db_ = -60.0;
    return false;  // silence or corrupted samples: neither a detection nor a noise sample
  }
  const double coherence = std::clamp(input.mean_coherence, 0.0, 0.999);
  const double noise_dbfs = to_db(power * (1.0 - coherence));
  if (!has_floor_) {
    floor_dbfs_ = noise_dbfs;
    has_floor_ = true;
  } else if (noise_dbfs < floor_dbfs_) {
    floor_dbfs_ += settings_.floor_fall_fraction * (noise_dbfs - floor_dbfs_);
  } else {
    floor_dbfs_ += std::min(noise_dbfs - floor_dbfs_, max_rise_db_per_frame_);
  }
  const double floor_power = std::pow(10.0, floor_dbfs_ / 10.0);
  snr_db_ = std::max(-60.0, to_db(power / floor_power - 1.0));
  detecting_ =
      snr_db_ >= settings_.detection_snr_db && input.mean_peak_value >= settings_.min_peak_value;
  return detecting_;
}

}  // namespace dronetrack::doa
