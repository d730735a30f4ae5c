// GccPhat, part 1: the band, the lag grid's layout, whitening and the cross-power of the pairs
// (gcc_correlation.cpp: the lag grids; gcc_peaks.cpp: peak search and refinement).
#include "doa/gcc_phat.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "doa/doa_measurement.hpp"
#include "doa/fftw_lock.hpp"
#include "doa/gcc_phat_internal.hpp"
#include "doa/simd/dispatch.hpp"
#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

using namespace gcc_internal;

std::vector<BandRun> band_runs(const std::vector<FrequencyBand>& bands, double sample_rate_hz,
                               int fft_size) {
  const int last_usable = fft_size / 2 - 1;
  std::vector<bool> inside(static_cast<std::size_t>(fft_size / 2 + 1), false);
  for (const FrequencyBand& band : bands) {
    const int first =
        std::max(1, static_cast<int>(std::ceil(band.low_hz * fft_size / sample_rate_hz)));
    const int last = std::min(
        last_usable, static_cast<int>(std::floor(band.high_hz * fft_size / sample_rate_hz)));
    for (int k = first; k <= last; ++k) inside[static_cast<std::size_t>(k)] = true;
  }
  std::vector<BandRun> runs;
  for (int k = 1; k <= last_usable; ++k) {
    if (!inside[static_cast<std::size_t>(k)]) continue;
    if (!runs.empty() && runs.back().last_bin == k - 1) {
      runs.back().last_bin = k;
    } else {
      runs.push_back({k, k});
    }
  }
  if (runs.empty())
    throw std::invalid_argument("bands_hz: no FFT bin inside the bands below Nyquist (" +
                                std::to_string(sample_rate_hz / 2.0) + " Hz)");
  return runs;
}

GccPhat::GccPhat(int fft_size, int frame_length, double sample_rate_hz,
                 const std::vector<FrequencyBand>& bands, std::vector<MicPairSpec> pairs,
                 LagInterpolation interpolation, int oversample)
    : sample_rate_hz_(sample_rate_hz),
      fft_size_(fft_size),
      bin_omega_(2.0 * std::numbers::pi * sample_rate_hz / fft_size),
      runs_(band_runs(bands, sample_rate_hz, fft_size)),
      interpolation_(interpolation),
      pairs_(std::move(pairs)),
      inverse_(std::make_unique<Inverse>()) {
  if (pairs_.empty()) throw std::invalid_argument("GccPhat: needs at least one mic pair");
  if (oversample < 1 || oversample > 64)
    throw std::invalid_argument("GccPhat: oversample must be in [1, 64]");
  for (const BandRun& run : runs_) {
    band_bins_ += run.last_bin - run.first_bin + 1;
    for (int k = run.first_bin; k <= run.last_bin; ++k)
      sum_omega2_ += (k * bin_omega_) * (k * bin_omega_);
  }
  // Hann window: neighbouring bins share phase noise (equivalent noise bandwidth 1.5 bins);
  // zero padding beyond the frame interpolates bins further.
  bin_correlation_ = 1.5 * static_cast<double>(fft_size) / frame_length;

  const int top_bin = runs_.back().last_bin;
  correlation_size_ = 2;
  while (correlation_size_ / 2 <= top_bin) correlation_size_ *= 2;
  correlation_size_ *= oversample;
  lag_step_s_ = static_cast<double>(fft_size) / correlation_size_ / sample_rate_hz;

  int max_half_span = 0;
  for (const MicPairSpec& pair : pairs_) {
    if (!(pair.max_lag_s > 0.0))
      throw std::invalid_argument("GccPhat: mic pair " + std::to_string(pair.mic_i) + "-" +
                                  std::to_string(pair.mic_j) + " has zero spacing");
    // One extra grid step so a peak at the physical limit is still a local maximum.
    int half_span = static_cast<int>(std::ceil(pair.max_lag_s / lag_step_s_)) + 1;
    half_span = std::min(half_span, correlation_size_ / 2 - 1);
    half_spans_.push_back(half_span);
    max_half_span = std::max(max_half_span, half_span);
  }
  grid_stride_ = 2 * max_half_span + 1;
  // Kernel table: offsets up to two maximal lags (two sources at opposite ends), 1/8 grid step.
  kernel_step_s_ = lag_step_s_ / 8.0;
  const int kernel_size = 16 * (2 * max_half_span + 2) + 2;
  kernel_table_.resize(static_cast<std::size_t>(kernel_size));
  std::fill(kernel_table_.begin(), kernel_table_.end(), 0.0);
  for (const BandRun& run : runs_) {
    for (int k = run.first_bin; k <= run.last_bin; ++k) {
      // cos(k w n step) for all n by a complex rotation: no trigonometry per entry.
      const std::complex<double> step = std::polar(1.0, k * bin_omega_ * kernel_step_s_);
      std::complex<double> rotation{1.0, 0.0};
      for (double& entry : kernel_table_) {
        entry += rotation.real();
        rotation *= step;
      }
    }
  }
  for (double& entry : kernel_table_) entry /= band_bins_;
  grids_.assign(static_cast<std::size_t>(grid_stride_) * pairs_.size(), 0.0);
  results_.assign(pairs_.size(), PairCorrelation{});
  phasors_.assign(static_cast<std::size_t>(band_bins_) * pairs_.size(), {0.0, 0.0});
  magnitudes_.assign(static_cast<std::size_t>(band_bins_) * pairs_.size(), 0.0);
  magnitude_sums_.assign(pairs_.size(), 0.0);
  keep_.assign(static_cast<std::size_t>(band_bins_), 1);
  kept_bins_ = band_bins_;
  kept_weight_ = band_bins_;
  effective_bins_ = band_bins_;
  kept_sum_omega2_ = sum_omega2_;
  kept_sum_w2_omega2_ = sum_omega2_;
  weights_.assign(static_cast<std::size_t>(band_bins_), 1.0);

  for (const MicPairSpec& pair : pairs_)
    unit_channels_ = std::max({unit_channels_, pair.mic_i + 1, pair.mic_j + 1});
  unit_re_.assign(static_cast<std::size_t>(unit_channels_) * static_cast<std::size_t>(band_bins_),
                  0.0);
  unit_im_.assign(unit_re_.size(), 0.0);
  phasor_keep_.assign(static_cast<std::size_t>(band_bins_), 1);
  levels_.assign(unit_re_.size(), 0.0);
  powers_.assign(unit_re_.size(), 0.0);
  for (const BandRun& run : runs_)
    for (int k = run.first_bin; k <= run.last_bin; ++k) band_fft_bins_.push_back(k);
  refined_index_.assign(pairs_.size(), -1);
  refined_ok_.assign(pairs_.size(), 0);
  refined_peaks_.assign(pairs_.size(), GccPeak{});

  // The search only reads 2 * half_span + 1 lags of the correlation_size_ points the inverse
  // FFT makes. When few bins are kept (the re-correlations after a loud source's bins are
  // dropped: typically 10-30 % of the band) the lags are cheaper summed directly over the kept
  // bins: per bin one row of cos and one of sin over lags 0..max_half_span, each product used
  // for +m and -m. Same sums as the inverse FFT, up to rounding (both single precision). Per
  // frame correlate() takes the cheaper of the two from the count of kept bins and the target's
  // lanes (kDirectProductsPerFftPoint*, measured): with 8 or more float lanes the whole band at
  // the defaults is summed directly too.
  lag_rows_ = max_half_span + 1;
  lag_stride_ = (lag_rows_ + simd::kLagStrideMultiple - 1) / simd::kLagStrideMultiple *
                simd::kLagStrideMultiple;  // whole blocks, zeros after
  const int float_lanes = 2 * simd_double_lanes();
  max_direct_products_ = (float_lanes >= 16  ? kDirectProductsPerFftPoint16
                          : float_lanes >= 8 ? kDirectProductsPerFftPoint8
                                             : kDirectProductsPerFftPoint4) *
                         correlation_size_ * std::log2(static_cast<double>(correlation_size_));
  // No table when too few kept bins to correlate at all would already cost more than the FFT.
  if (max_direct_products_ / lag_rows_ >= std::max(1.0, kMinKeptShare * band_bins_)) {
    const std::size_t row = 2 * static_cast<std::size_t>(lag_stride_);
    lag_table_.assign(static_cast<std::size_t>(band_bins_) * row, 0.0F);
    phasor_floats_.assign(2 * static_cast<std::size_t>(band_bins_) * pairs_.size(), 0.0F);
    // Angles 2 pi k m / N are multiples of 2 pi / N: reduced exactly in integers and looked up.
    std::vector<std::complex<double>> circle(static_cast<std::size_t>(correlation_size_));
    for (int n = 0; n < correlation_size_; ++n)
      circle[static_cast<std::size_t>(n)] =
          std::polar(1.0, 2.0 * std::numbers::pi * n / correlation_size_);
    std::size_t index = 0;
    for (const BandRun& run : runs_) {
      for (int k = run.first_bin; k <= run.last_bin; ++k, index += row) {
        for (int m = 0; m < lag_rows_; ++m) {
          const std::complex<double> turn = circle[static_cast<std::size_t>(
              static_cast<std::int64_t>(k) * m % correlation_size_)];
          lag_table_[index + static_cast<std::size_t>(m)] = static_cast<float>(turn.real());
          lag_table_[index + static_cast<std::size_t>(lag_stride_ + m)] =
              static_cast<float>(turn.imag());
        }
      }
    }
  } else {
    max_direct_products_ = 0.0;
  }
  kept_indices_.assign(static_cast<std::size_t>(band_bins_), 0);
  for (const BandRun& run : runs_)
    for (int k = run.first_bin; k <= run.last_bin; ++k)
      band_omega2_.push_back((k * bin_omega_) * (k * bin_omega_));
  bin_scales_.assign(static_cast<std::size_t>(band_bins_), 1.0);
  bin_keeps_.assign(static_cast<std::size_t>(band_bins_), 1.0);
  const std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  inverse_->spectrum = fftwf_alloc_complex(static_cast<std::size_t>(correlation_size_ / 2 + 1));
  inverse_->correlation = fftwf_alloc_real(static_cast<std::size_t>(correlation_size_));
  if (inverse_->spectrum == nullptr || inverse_->correlation == nullptr) throw std::bad_alloc();
  std::fill_n(reinterpret_cast<float*>(inverse_->spectrum), correlation_size_ + 2, 0.0f);
  inverse_->plan = fftwf_plan_dft_c2r_1d(correlation_size_, inverse_->spectrum,
                                         inverse_->correlation, FFTW_ESTIMATE);
  if (inverse_->plan == nullptr) throw std::runtime_error("GccPhat: FFTW plan failed");
}

GccPhat::~GccPhat() {
  if (!inverse_ || inverse_->plan == nullptr) return;
  const std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  if (inverse_->plan != nullptr) fftwf_destroy_plan(inverse_->plan);
  fftwf_free(inverse_->spectrum);
  fftwf_free(inverse_->correlation);
}

std::span<const double> GccPhat::grid(int pair) const {
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  return {grids_.data() + static_cast<std::ptrdiff_t>(pair) * grid_stride_,
          static_cast<std::size_t>(2 * half + 1)};
}

std::span<const std::complex<double>> GccPhat::phasors(int pair) const {
  return {phasors_.data() + static_cast<std::ptrdiff_t>(pair) * band_bins_,
          static_cast<std::size_t>(band_bins_)};
}

std::span<const double> GccPhat::magnitudes(int pair) const {
  return {magnitudes_.data() + static_cast<std::ptrdiff_t>(pair) * band_bins_,
          static_cast<std::size_t>(band_bins_)};
}

GccPhat::UnitsView GccPhat::units() const { return {unit_re_.data(), unit_im_.data(), band_bins_}; }

void GccPhat::cross_power(const UnitsView& units, std::span<const std::uint8_t> keep,
                          bool weighted) {
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  if (keep.data() != keep_.data()) std::copy(keep.begin(), keep.end(), keep_.begin());
  pair_phasors(units, true, weighted);
}

void GccPhat::cross_power_from(std::span<const std::complex<double>> given_phasors,
                               std::span<const std::uint8_t> keep) {
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  if (keep.data() != keep_.data()) std::copy(keep.begin(), keep.end(), keep_.begin());
  pair_phasors(units(), true, false, given_phasors.data());
}

void GccPhat::cross_power_from(std::span<const std::complex<double>> given_phasors,
                               std::span<const std::uint8_t> keep, const BinOwners& owners) {
  static_assert(BinOwners::kMaxTerms <= simd::kMaxLookTerms);
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  if (keep.data() != keep_.data()) std::copy(keep.begin(), keep.end(), keep_.begin());
  for (double& w : weights_) w = std::clamp(w, kMinWeight, 1.0);
  const auto bins = static_cast<std::size_t>(band_bins_);
  std::array<const double*, kMaxPairs> given{}, level_i{}, level_j{};
  std::array<double*, kMaxPairs> out{}, magnitudes{};
  std::array<float*, kMaxPairs> floats{};
  for (std::size_t p = 0; p < pairs_.size(); ++p) {
    given[p] = reinterpret_cast<const double*>(given_phasors.data() + p * bins);
    level_i[p] = levels_.data() + static_cast<std::size_t>(pairs_[p].mic_i) * bins;
    level_j[p] = levels_.data() + static_cast<std::size_t>(pairs_[p].mic_j) * bins;
    out[p] = reinterpret_cast<double*>(phasors_.data() + p * bins);
    floats[p] = phasor_floats(p);
    magnitudes[p] = magnitudes_.data() + p * bins;
  }
  simd::look_phasors({runs_.data(), runs_.size(), bin_omega_, pair_count(), given.data(),
                      level_i.data(), level_j.data(), kSilentBin, keep_.data(), weights_.data(),
                      owners.pairs.data(), owners.taus_s.data(), owners.starts.data(),
                      owners.sources, owners.thresholds.data(), out.data(), floats.data(),
                      magnitudes.data(), magnitude_sums_.data()});
  // The phasors carry the final mask and the weights, with their sums: prepare() only sums.
  weights_applied_ = true;
  sums_weighted_ = true;
  prepared_ = false;
  whitened_ = false;
  std::copy(keep_.begin(), keep_.end(), phasor_keep_.begin());
}

void GccPhat::redirect_phasor(int pair, int band_index, std::complex<double> cross_power) {
  const std::size_t at = static_cast<std::size_t>(pair) * static_cast<std::size_t>(band_bins_) +
                         static_cast<std::size_t>(band_index);
  // Squared norms and one root (std::abs on a complex is a hypot: slower, and not needed here).
  const double length2 = std::norm(cross_power);
  if (!(length2 > 0.0)) return;
  const std::complex<double> phasor = std::sqrt(std::norm(phasors_[at]) / length2) * cross_power;
  phasors_[at] = phasor;
  if (float* floats = phasor_floats(static_cast<std::size_t>(pair)); floats != nullptr) {
    floats[2 * static_cast<std::size_t>(band_index)] = static_cast<float>(phasor.real());
    floats[2 * static_cast<std::size_t>(band_index) + 1] = static_cast<float>(phasor.imag());
  }
  refined_index_[static_cast<std::size_t>(pair)] = -1;
  whitened_ = false;
}

void GccPhat::process(const MultichannelFft& spectra) {
  whiten(spectra);
  correlate();
}

void GccPhat::whiten(const MultichannelFft& spectra) {
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  // W_ij = X_i X_j* / |X_i X_j*| = (X_i / |X_i|) (X_j / |X_j|)*: each channel is normalised
  // once (a square root and a division per bin and mic, not per bin and pair), the pairs are
  // products of unit phasors and |G_ij| = |X_i| |X_j|.
  // Units are kept as separate real and imaginary rows so that every loop below runs two bins
  // per SIMD instruction.
  const auto bins = static_cast<std::size_t>(band_bins_);
  for (int mic = 0; mic < unit_channels_; ++mic) {
    const std::complex<double>* x = spectra.spectrum(mic);
    const std::size_t row = static_cast<std::size_t>(mic) * bins;
    double* unit_re = unit_re_.data() + row;
    double* unit_im = unit_im_.data() + row;
    double* level = levels_.data() + row;
    // One pass per mic: |X|^2 (kept: band_powers()), 1/|X|, then |X| = |X|^2 / |X| and the unit
    // X / |X|. A silent bin (X = 0) gets the unit phasor 0.
    simd::unit_phasors(
        {x, band_fft_bins_.data(), bins, powers_.data() + row, level, {unit_re, unit_im}});
  }
  std::fill(keep_.begin(), keep_.end(), std::uint8_t{1});
  pair_phasors(units(), false, false);
  whitened_ = true;
}

void GccPhat::set_bin_spectrum(int band_index, std::span<const std::complex<double>> spectrum) {
  const auto bins = static_cast<std::size_t>(band_bins_);
  for (int mic = 0; mic < unit_channels_; ++mic) {
    const std::size_t index =
        static_cast<std::size_t>(mic) * bins + static_cast<std::size_t>(band_index);
    const std::complex<double> x = spectrum[static_cast<std::size_t>(mic)];
    const double level = std::abs(x);
    levels_[index] = level;
    unit_re_[index] = level > 0.0 ? x.real() / level : 0.0;
    unit_im_[index] = level > 0.0 ? x.imag() / level : 0.0;
  }
  prepared_ = false;
}

void GccPhat::remake_bins(std::span<const std::uint8_t> changed) {
  if (!whitened_)
    throw std::logic_error("GccPhat::remake_bins: the phasors are no longer whiten()'s");
  const auto bins = static_cast<std::size_t>(band_bins_);
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  // Runs of changed bins, each through the whitening's own kernel: the same products per bin
  // (the kernel's arithmetic is lane by lane, wherever a run starts). A short gap between two
  // runs is remade with them: its bins' units are unchanged, so are their products, and one
  // call is cheaper than two (a projection keeps bins scattered over the band).
  constexpr std::size_t kJoinedGap = 16;
  std::size_t first = 0;
  while (first < bins) {
    if (changed[first] == 0) {
      ++first;
      continue;
    }
    std::size_t end = first + 1;
    for (std::size_t next = end; next < bins && next < end + kJoinedGap; ++next)
      if (changed[next] != 0) end = next + 1;
    for (std::size_t p = 0; p < pairs_.size(); ++p) {
      const std::size_t row_i = static_cast<std::size_t>(pairs_[p].mic_i) * bins + first;
      const std::size_t row_j = static_cast<std::size_t>(pairs_[p].mic_j) * bins + first;
      float* floats = phasor_floats(p);
      simd::pair_products({{unit_re_.data() + row_i, unit_im_.data() + row_i},
                           {unit_re_.data() + row_j, unit_im_.data() + row_j},
                           levels_.data() + row_i,
                           levels_.data() + row_j,
                           nullptr,
                           nullptr,
                           end - first,
                           kSilentBin,
                           nullptr,
                           reinterpret_cast<double*>(phasors_.data() + p * bins + first),
                           floats != nullptr ? floats + 2 * first : nullptr,
                           magnitudes_.data() + p * bins + first});
    }
    first = end;
  }
  // The magnitudes' sums are whiten()'s no more: the next correlation sums them again.
  sums_weighted_.reset();
  prepared_ = false;
}

void GccPhat::pair_phasors(const UnitsView& units, bool masked, bool weighted,
                           const std::complex<double>* given) {
  // W_ij = u_i u_j* and |G_ij| = |X_i| |X_j| from whiten()'s per-mic rows; `masked`: bins
  // dropped in keep_ zero; `weighted`: the phasors times the bins' weights, as a weighted
  // prepare() would scale them (the same product: live x w is w or 0).
  const auto bins = static_cast<std::size_t>(band_bins_);
  if (weighted)
    for (double& w : weights_) w = std::clamp(w, kMinWeight, 1.0);
  const double* weights = weighted ? weights_.data() : nullptr;
  for (std::size_t p = 0; p < pairs_.size(); ++p) {
    const auto mic_i = static_cast<std::size_t>(pairs_[p].mic_i);
    const auto mic_j = static_cast<std::size_t>(pairs_[p].mic_j);
    const std::size_t row_i = mic_i * bins;
    const std::size_t row_j = mic_j * bins;
    const double* a_re = units.real + row_i;
    const double* a_im = units.imag + row_i;
    const double* b_re = units.real + row_j;
    const double* b_im = units.imag + row_j;
    const double* level_i = levels_.data() + row_i;
    const double* level_j = levels_.data() + row_j;
    double* out = reinterpret_cast<double*>(phasors_.data() + p * bins);
    double* magnitude = magnitudes_.data() + p * bins;
    const double magnitude_sum = simd::pair_products(
        {{a_re, a_im},
         {b_re, b_im},
         level_i,
         level_j,
         masked ? keep_.data() : nullptr,
         weights,
         bins,
         kSilentBin,
         given != nullptr ? reinterpret_cast<const double*>(given + p * bins) : nullptr,
         out,
         phasor_floats(p),
         magnitude});
    magnitude_sums_[p] = magnitude_sum;
  }
  weights_applied_ = weighted;
  prepared_ = false;
  whitened_ = false;  // whiten() sets it again after this
  sums_weighted_ = weighted;
  // The mask the phasors now carry: prepare() need not scale them again for it.
  if (masked)
    std::copy(keep_.begin(), keep_.end(), phasor_keep_.begin());
  else
    std::fill(phasor_keep_.begin(), phasor_keep_.end(), std::uint8_t{1});
}

}  // namespace dronetrack::doa
