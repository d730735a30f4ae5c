#include "doa/bin_snr_weight.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

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

void BinSnrWeight::update(const MultichannelFft& spectra, std::span<double> weights) {
  std::fill(power_.begin(), power_.end(), 0.0);
  const double per_channel = 1.0 / spectra.channels();
  for (int c = 0; c < spectra.channels(); ++c) {
    const std::complex<double>* x = spectra.spectrum(c);
    std::size_t index = 0;
    for (const BandRun& run : runs_) {
      for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
        power_[index] += per_channel * std::norm(x[k]);
      }
    }
  }
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
  // Two bins per step and no branches: whether a bin's SNR is above 0 is a coin toss in noise
  // (a branch per bin mispredicted half the time cost more than the arithmetic). The selects
  // are std::min / std::max exactly (finite values).
  using Lanes = double __attribute__((vector_size(16)));
  const Lanes smoothing{kSmoothing, kSmoothing};
  const Lanes fresh{1.0 - kSmoothing, 1.0 - kSmoothing};
  const Lanes rise{rise_per_update_, rise_per_update_};
  const Lanes tiny{kTinyPower, kTinyPower};
  const Lanes bias{kMinimumBias, kMinimumBias};
  const Lanes one{1.0, 1.0};
  const Lanes zero{0.0, 0.0};
  const Lanes floor{floor_, floor_};
  std::size_t k = 0;
  for (; k + 2 <= power_.size(); k += 2) {
    Lanes smoothed, noise, power;
    std::memcpy(&smoothed, smoothed_.data() + k, sizeof smoothed);
    std::memcpy(&noise, noise_.data() + k, sizeof noise);
    std::memcpy(&power, power_.data() + k, sizeof power);
    smoothed = smoothing * smoothed + fresh * power;
    const Lanes risen = noise * rise;
    const Lanes lower = risen < smoothed ? risen : smoothed;  // std::min(smoothed, risen)
    noise = lower < tiny ? tiny : lower;                      // std::max(lower, tiny)
    const Lanes excess = smoothed / (bias * noise) - one;
    const Lanes snr = excess < zero ? zero : excess;
    const Lanes gain = snr / (one + snr);
    const Lanes weight = gain < floor ? floor : gain;
    std::memcpy(smoothed_.data() + k, &smoothed, sizeof smoothed);
    std::memcpy(noise_.data() + k, &noise, sizeof noise);
    std::memcpy(weights.data() + k, &weight, sizeof weight);
  }
  for (; k < power_.size(); ++k) {
    smoothed_[k] = kSmoothing * smoothed_[k] + (1.0 - kSmoothing) * power_[k];
    noise_[k] = std::max(std::min(smoothed_[k], noise_[k] * rise_per_update_), kTinyPower);
    const double snr = std::max(smoothed_[k] / (kMinimumBias * noise_[k]) - 1.0, 0.0);
    weights[k] = std::max(snr / (1.0 + snr), floor_);
  }
}

}  // namespace dronetrack::doa
