// GccPhat, part 2: the band-limited cross-power evaluated on the lag grid (the mask and weights
// applied, the normalisation, direct sums over the kept bins or the inverse FFT) and at any lag.
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

#include "doa/gcc_phat.hpp"
#include "doa/gcc_phat_internal.hpp"
#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

using namespace gcc_internal;

bool GccPhat::prepare(bool weighted) {
  // The phasors carry the weights of the last weighted correlate() until whiten() or
  // cross_power() makes them again: a change of mind scales each bin by w or 1 / w.
  const bool rescale = weighted != weights_applied_;
  // Weights change only on plain phasors (bin_weight()): bounded once, as they go on.
  if (rescale && weighted)
    for (double& w : weights_) w = std::clamp(w, kMinWeight, 1.0);
  // Per bin, vectorised: the kept bins' sums and each bin's scale and keep (bin_scales_,
  // bin_keeps_; used below when bins are dropped or the weights change).
  const auto bins = static_cast<std::size_t>(band_bins_);
  const simd::KeptSums totals =
      simd::kept_sums({keep_.data(), weights_.data(), band_omega2_.data(), bins, weighted,
                       !rescale   ? simd::Rescale::none
                       : weighted ? simd::Rescale::weight
                                  : simd::Rescale::inverse,
                       bin_scales_.data(), bin_keeps_.data()});
  const int kept = static_cast<int>(totals.kept + 0.5);
  const double sum_w = totals.w;
  const double sum_w2 = totals.w2;
  const double sum_omega2 = totals.omega2;
  const double sum_w2_omega2 = totals.w2_omega2;
  const double sum_omega4 = totals.omega4;
  kept_bins_ = kept;
  kept_weight_ = sum_w;
  kept_sum_omega2_ = sum_omega2;
  kept_sum_w2_omega2_ = sum_w2_omega2;
  // An upper bound either way: weights are at most 1.
  taylor_bound_ = runs_.back().last_bin * bin_omega_ * sum_omega4;
  const double effective = sum_w2 > 0.0 ? sum_w * sum_w / sum_w2 : 0.0;
  effective_bins_ = static_cast<int>(effective + 0.5);
  const bool enough_bins = effective >= std::max(1.0, kMinKeptShare * band_bins_);
  if (!enough_bins) {
    kept_bins_ = std::max(kept_bins_, 1);
    effective_bins_ = std::max(effective_bins_, 1);
    kept_weight_ = std::max(kept_weight_, 1.0);
    kept_sum_omega2_ = std::max(kept_sum_omega2_, bin_omega_ * bin_omega_);
    kept_sum_w2_omega2_ = std::max(kept_sum_w2_omega2_, bin_omega_ * bin_omega_);
  }
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  const bool all_kept = kept == band_bins_;
  // Dropped bins leave the phasors too: refinement and coherence see the kept bins only.
  // Scaling by 0 or 1 instead of a branch per bin (phasors and magnitudes are finite). In the
  // same pass, coherence's total: the magnitude-weighted correlation over the same weights, in
  // four partial sums (one would make every bin wait for the previous addition).
  // The single-precision copy is read by the direct sums alone, at the kept bins alone: a mask
  // leaves the kept bins' values as they were (times 1), only new weights change them.
  const auto scale_and_sum = [&](bool scale, bool weighted_sum) {
    for (std::size_t p = 0; p < pairs_.size(); ++p)
      magnitude_sums_[p] = simd::scale_and_sum(
          {reinterpret_cast<double*>(phasors_.data() + p * bins),
           rescale ? phasor_floats(p) : nullptr, magnitudes_.data() + p * bins, bin_scales_.data(),
           bin_keeps_.data(), weighted_sum ? weights_.data() : nullptr, scale, bins});
  };
  // Dropped bins already zero in the phasors (made under this very mask) need no pass of
  // their own.
  const bool masked_already = std::equal(keep_.begin(), keep_.end(), phasor_keep_.begin());
  const bool scale = (!all_kept && !masked_already) || rescale;
  if (scale) std::copy(keep_.begin(), keep_.end(), phasor_keep_.begin());
  // Phasors made under this mask and weighting (pair_phasors()) came with their sums.
  const bool summed = !scale && masked_already && sums_weighted_ && *sums_weighted_ == weighted;
  if (scale || !summed) scale_and_sum(scale, weighted);
  if (scale) whitened_ = false;
  weights_applied_ = weighted;
  sums_weighted_ = weighted;
  enough_bins_ = enough_bins;
  prepared_ = true;
  return enough_bins;
}

void GccPhat::correlate(bool refine_peaks, bool weighted) {
  const bool enough_bins = prepare(weighted);
  const double normalisation = 1.0 / kept_weight_;
  const bool direct = static_cast<double>(kept_bins_) * lag_rows_ <= max_direct_products_;
  if (enough_bins && direct) direct_grids(normalisation);
  for (std::size_t p = 0; p < pairs_.size(); ++p) {
    results_[p] = PairCorrelation{};
    if (!enough_bins) continue;
    if (!direct)
      inverse_grid(p, normalisation, grids_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_);
    if (refine_peaks) search_peaks(p);
  }
}

void GccPhat::direct_grids(double normalisation) {
  // R(+-m) = (1/K) sum_k (Re W_k cos(w_k m step) -+ Im W_k sin(w_k m step)) over the kept
  // bins. Per pair and block of kLagBlock lags the sums stay in registers over all kept bins.
  // The kept bins' band indices first (only the direct sums use them), without a branch per bin.
  int kept = 0;
  for (int index = 0; index < band_bins_; ++index) {
    kept_indices_[static_cast<std::size_t>(kept)] = index;
    kept += keep_[static_cast<std::size_t>(index)] != 0 ? 1 : 0;
  }
  simd::direct_grids({phasor_floats_.data(), static_cast<std::size_t>(band_bins_), grids_.data(),
                      static_cast<std::size_t>(grid_stride_), half_spans_.data(),
                      static_cast<int>(pairs_.size()), lag_table_.data(),
                      static_cast<std::size_t>(lag_stride_), kept_indices_.data(), kept_bins_,
                      normalisation});
}

void GccPhat::inverse_grid(std::size_t pair, double normalisation, double* grid_values) {
  auto* inverse_bins = reinterpret_cast<float*>(inverse_->spectrum);
  // c2r transforms destroy their input: clear it for every pair.
  std::fill_n(inverse_bins, correlation_size_ + 2, 0.0f);
  const auto* phasor = reinterpret_cast<const double*>(phasors_.data() +
                                                       pair * static_cast<std::size_t>(band_bins_));
  int index = 0;
  for (const BandRun& run : runs_)
    for (int k = 2 * run.first_bin; k <= 2 * run.last_bin + 1; ++k, ++index)
      inverse_bins[k] = static_cast<float>(phasor[index]);
  fftwf_execute(inverse_->plan);
  // The c2r sums both halves of the spectrum: 2 Re(...) per bin.
  const int half = half_spans_[pair];
  const double scale = 0.5 * normalisation;
  for (int m = -half; m <= half; ++m) {
    const int index_circular = m >= 0 ? m : correlation_size_ + m;
    grid_values[m + half] = static_cast<double>(inverse_->correlation[index_circular]) * scale;
  }
}

double GccPhat::value_at(int pair, double lag_s) const {
  double value = 0.0;
  double coherence = 0.0;
  evaluate(pair, lag_s, value, coherence);
  return value;
}

double GccPhat::coherence_at(int pair, double lag_s) const {
  double value = 0.0;
  double coherence = 0.0;
  evaluate(pair, lag_s, value, coherence);
  return coherence;
}

void GccPhat::evaluate(int pair, double lag_s, double& value, double& coherence) const {
  const std::size_t offset = static_cast<std::size_t>(pair) * static_cast<std::size_t>(band_bins_);
  double sum = 0.0;
  double weighted = 0.0;
  int index = 0;
  const std::complex<double> step = std::polar(1.0, bin_omega_ * lag_s);
  for (const BandRun& run : runs_) {
    std::complex<double> rotation = std::polar(1.0, bin_omega_ * run.first_bin * lag_s);
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      const double real = (phasors_[offset + static_cast<std::size_t>(index)] * rotation).real();
      sum += real;
      weighted += magnitudes_[offset + static_cast<std::size_t>(index)] * real;
      rotation *= step;
    }
  }
  value = sum / kept_weight_;
  const double total = magnitude_sums_[static_cast<std::size_t>(pair)];
  coherence = total > 0.0 ? std::clamp(weighted / total, 0.0, 1.0) : 0.0;
}

double GccPhat::grid_value(int pair, double lag_s) const {
  const std::span<const double> values = grid(pair);
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  const double position = lag_s / lag_step_s_ + half;
  if (!(position >= 0.0) || position > 2.0 * half) return 0.0;
  const int below = std::min(static_cast<int>(position), 2 * half - 1);
  const double fraction = position - below;
  return values[static_cast<std::size_t>(below)] * (1.0 - fraction) +
         values[static_cast<std::size_t>(below + 1)] * fraction;
}

double GccPhat::phat_kernel(double offset_s) const {
  const double position = std::abs(offset_s) / kernel_step_s_;
  const auto below = static_cast<std::size_t>(position);
  if (below + 1 >= kernel_table_.size()) return 0.0;
  const double fraction = position - static_cast<double>(below);
  return kernel_table_[below] * (1.0 - fraction) + kernel_table_[below + 1] * fraction;
}

}  // namespace dronetrack::doa
