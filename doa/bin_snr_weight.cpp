#include "doa/bin_snr_weight.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

namespace {
// Recursive smoothing of the per-bin power: ~2.5 frames' memory, so a drone's harmonic that
// moves by a bin per frame still stands out.
constexpr double kSmoothing = 0.6;
// Minimum tracking sits on the low tail of the smoothed power's distribution (about 8 degrees
// of freedom at this smoothing): the mean noise power is about twice the tracked minimum. A bin
// counts as signal only above that.
constexpr double kMinimumBias = 2.0;
constexpr double kTinyPower = 1e-30;
}  // namespace

BinSnrWeight::BinSnrWeight(std::vector<BandRun> runs, double hop_s, double noise_rise_db_per_s,
                           double floor)
    : runs_(std::move(runs)), floor_(floor) {
  if (!(hop_s > 0.0) || !(noise_rise_db_per_s > 0.0))
    throw std::invalid_argument("BinSnrWeight: hop and noise rise must be > 0");
  for (const BandRun& run : runs_) band_bins_ += run.last_bin - run.first_bin + 1;
  rise_per_update_ = std::pow(10.0, noise_rise_db_per_s * hop_s / 10.0);
  power_.assign(static_cast<std::size_t>(band_bins_), 0.0);
  smoothed_ = power_;
  noise_ = power_;
}

void BinSnrWeight::update(std::span<const double> channel_powers, int channels,
                          std::span<double> weights) {
  std::fill(power_.begin(), power_.end(), 0.0);
  const double per_channel = 1.0 / channels;
  const auto bins = power_.size();
  for (int c = 0; c < channels; ++c) {
    const double* row = channel_powers.data() + static_cast<std::size_t>(c) * bins;
    for (std::size_t index = 0; index < bins; ++index) power_[index] += per_channel * row[index];
  }
  weigh(weights);
}

void BinSnrWeight::weigh(std::span<double> weights) {
  bool finite = true;
  for (const double p : power_) finite = finite && std::isfinite(p);
  if (!finite) {
    std::fill(weights.begin(), weights.end(), 1.0);
    return;
  }
  if (!started_) {
    smoothed_ = power_;
    noise_ = power_;
    started_ = true;
  }
  simd::snr_weights({power_.data(), smoothed_.data(), noise_.data(), weights.data(), power_.size(),
                     kSmoothing, rise_per_update_, kTinyPower, kMinimumBias, floor_});
}

}  // namespace dronetrack::doa
