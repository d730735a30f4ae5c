#include "doa/acoustic_features.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>

#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

namespace {

BandRun feature_bins(const FrequencyBand& band_hz, double sample_rate_hz, int fft_size) {
  const std::vector<BandRun> runs = band_runs({band_hz}, sample_rate_hz, fft_size);
  return {runs.front().first_bin, runs.back().last_bin};
}

}  // namespace

AcousticFeatureExtractor::AcousticFeatureExtractor(const ArrayGeometry& geometry, int fft_size,
                                                   double sample_rate_hz, double speed_of_sound_mps,
                                                   double hop_s, const AcousticSettings& settings)
    : settings_(settings),
      mic_count_(static_cast<int>(geometry.mic_count())),
      band_(feature_bins(settings.band_hz, sample_rate_hz, fft_size)),
      first_bin_(band_.first_bin),
      bin_count_(band_.last_bin - band_.first_bin + 1),
      bin_omega_(2.0 * std::numbers::pi * sample_rate_hz / fft_size),
      speed_of_sound_mps_(speed_of_sound_mps),
      detector_(first_bin_, bin_count_, sample_rate_hz / fft_size, settings.comb) {
  if (settings.analysis_every_frames < 1)
    throw std::invalid_argument("acoustic features: analysis_every_frames must be >= 1");
  if (!(settings.comb_memory_s > 0.0) || !(settings.history_s > 0.0))
    throw std::invalid_argument("acoustic features: comb_memory_s and history_s must be > 0");
  if (mic_count_ < 2 || mic_count_ > kMaxMics)
    throw std::invalid_argument("acoustic features: 2 to 8 mics");
  interval_s_ = hop_s * settings.analysis_every_frames;
  comb_weight_ = std::min(1.0, interval_s_ / settings.comb_memory_s);
  const int entries =
      std::clamp(static_cast<int>(std::lround(settings.history_s / interval_s_)), 2, 256);
  const Eigen::Vector3d centre = geometry.centre_site_m();
  for (std::size_t m = 0; m < geometry.mic_count(); ++m)
    mic_offsets_site_m_.push_back(geometry.mic_site_m(m) - centre);
  source_power_.resize(static_cast<std::size_t>(kMaxSources * bin_count_));
  mic_power_.resize(static_cast<std::size_t>(bin_count_));
  sorted_power_.reserve(static_cast<std::size_t>(bin_count_));
  frame_autocorrelation_.resize(static_cast<std::size_t>(detector_.lag_count()));
  for (History& history : histories_) {
    history.mean_autocorrelation.assign(static_cast<std::size_t>(detector_.lag_count()), 0.0);
    history.entries.resize(static_cast<std::size_t>(entries));
  }
}

const AcousticFeatures& AcousticFeatureExtractor::features(int slot) const {
  if (slot < 0 || slot >= kMaxSlots) return none_;
  return histories_[static_cast<std::size_t>(slot)].features;
}

// Delay-and-sum per bin toward every source; the bin's power goes to the source that makes it
// most coherent, if coherent enough. A plane wave from direction u reaches mic m (offset d_m
// from the centroid) d_m.u / c early, so its phasor there is S e^{+j w d_m.u / c}.
void AcousticFeatureExtractor::assign_bins(const MultichannelFft& fft, int sources) {
  // Per bin the mics' mean power and the most coherent source's steered power (doa/simd); the
  // delays are one block of kMaxSources rows of kMaxMics.
  static_assert(kMaxSources <= simd::kMaxSteeredSources && kMaxMics <= simd::kMaxSteeredMics);
  static_assert(sizeof(delays_s_) == sizeof(double) * kMaxSources * kMaxMics);
  std::array<const std::complex<double>*, kMaxMics> spectra{};
  for (int m = 0; m < mic_count_; ++m) spectra[static_cast<std::size_t>(m)] = fft.spectrum(m);
  simd::steered_bins({spectra.data(), mic_count_, first_bin_, bin_count_, bin_omega_,
                      delays_s_.front().data(), kMaxMics, sources, settings_.min_bin_coherence,
                      mic_power_.data(), source_power_.data()});
  // A bin another source (or nobody) owns is this source's background: the frame's typical
  // bin power, or the bin's own if lower. Not zero: a sparse source's lines need a floor to
  // stand on; not the bin's own power: a broadband source would then see the other source's
  // lines as its own comb.
  sorted_power_.assign(mic_power_.begin(), mic_power_.end());
  const auto middle = sorted_power_.begin() + static_cast<std::ptrdiff_t>(sorted_power_.size() / 2);
  std::nth_element(sorted_power_.begin(), middle, sorted_power_.end());
  const double typical = *middle;
  for (int s = 0; s < sources; ++s) {
    double owned = 0.0;
    for (int i = 0; i < bin_count_; ++i) {
      double& power = source_power_[static_cast<std::size_t>(s * bin_count_ + i)];
      owned += power;
      if (power == 0.0) power = std::min(mic_power_[static_cast<std::size_t>(i)], typical);
    }
    owned_power_[static_cast<std::size_t>(s)] = owned;
  }
}

void AcousticFeatureExtractor::analyse(const MultichannelFft& fft,
                                       std::span<const Eigen::Vector3d> directions_site,
                                       std::span<const int> slots,
                                       std::span<const std::uint32_t> generations) {
  const int sources =
      std::min<int>({static_cast<int>(directions_site.size()), static_cast<int>(slots.size()),
                     static_cast<int>(generations.size()), kMaxSources});
  if (sources == 0 || fft.channels() != mic_count_) return;
  for (int s = 0; s < sources; ++s)
    for (int m = 0; m < mic_count_; ++m)
      delays_s_[s][m] = -mic_offsets_site_m_[static_cast<std::size_t>(m)].dot(
                            directions_site[static_cast<std::size_t>(s)]) /
                        speed_of_sound_mps_;
  assign_bins(fft, sources);
  // Power per windowed sample, one-sided (as the node's in-band level).
  const double to_power = 2.0 / (static_cast<double>(fft.fft_size()) * fft.window_energy());
  for (int s = 0; s < sources; ++s) {
    const int slot = slots[static_cast<std::size_t>(s)];
    if (slot < 0 || slot >= kMaxSlots) continue;
    History& history = histories_[static_cast<std::size_t>(slot)];
    const std::uint32_t generation = generations[static_cast<std::size_t>(s)];
    if (!history.started || history.generation != generation) {
      history.started = false;
      history.generation = generation;
      history.size = 0;
      history.next = 0;
    }
    const std::span<const double> power(source_power_.data() + s * bin_count_,
                                        static_cast<std::size_t>(bin_count_));
    const double band_power = owned_power_[static_cast<std::size_t>(s)];
    detector_.autocorrelate(power, frame_autocorrelation_);
    const double weight = history.started ? comb_weight_ : 1.0;
    for (std::size_t l = 0; l < frame_autocorrelation_.size(); ++l)
      history.mean_autocorrelation[l] +=
          weight * (frame_autocorrelation_[l] - history.mean_autocorrelation[l]);
    history.started = true;
    const HarmonicComb comb = detector_.find(history.mean_autocorrelation);
    update_history(history, comb, 10.0 * std::log10(std::max(band_power * to_power, 1e-30)));
  }
}

void AcousticFeatureExtractor::update_history(History& history, const HarmonicComb& comb,
                                              double level_db) {
  const auto capacity = static_cast<int>(history.entries.size());
  history.entries[static_cast<std::size_t>(history.next)] = {comb.found, comb.fundamental_hz,
                                                             level_db};
  history.next = (history.next + 1) % capacity;
  history.size = std::min(history.size + 1, capacity);

  int combs = 0;
  double f0_sum = 0.0;
  double f0_sum2 = 0.0;
  double level_sum = 0.0;
  double level_sum2 = 0.0;
  for (int i = 0; i < history.size; ++i) {
    const History::Entry& entry = history.entries[static_cast<std::size_t>(i)];
    level_sum += entry.level_db;
    level_sum2 += entry.level_db * entry.level_db;
    if (!entry.comb) continue;
    ++combs;
    f0_sum += entry.fundamental_hz;
    f0_sum2 += entry.fundamental_hz * entry.fundamental_hz;
  }
  AcousticFeatures& features = history.features;
  features.valid = true;
  features.fundamental_hz = comb.fundamental_hz;
  features.comb_strength = comb.strength;
  features.harmonic_count = comb.harmonic_count;
  features.broadband_share = 1.0 - comb.harmonic_share;
  features.comb_persistence = static_cast<double>(combs) / history.size;
  features.fundamental_spread = 0.0;
  if (combs >= 3) {
    const double mean = f0_sum / combs;
    const double variance = std::max(0.0, f0_sum2 / combs - mean * mean);
    features.fundamental_spread = mean > 0.0 ? std::sqrt(variance) / mean : 0.0;
  }
  const double level_mean = level_sum / history.size;
  features.level_modulation_db =
      std::sqrt(std::max(0.0, level_sum2 / history.size - level_mean * level_mean));
  features.history_s = history.size * interval_s_;
}

}  // namespace dronetrack::doa
