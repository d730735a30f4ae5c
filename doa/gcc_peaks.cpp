// GccPhat, part 3: peak search on the lag grid and sub-sample refinement (Newton on the
// continuous band-limited correlation, or a parabola through the grid).
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

void GccPhat::search_peaks(std::size_t p) {
  PairCorrelation& result = results_[p];
  const int half = half_spans_[p];
  const double* grid_values = grids_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_;
  // Highest and second-highest local maxima on the grid, and the peak_count_ highest.
  int best = -1;
  double best_value = -2.0;
  double second_value = -2.0;
  std::array<int, kMaxGccPeaks> top_index{};
  std::array<double, kMaxGccPeaks> top_value{};
  int top_count = 0;
  for (int m = 0; m < 2 * half + 1; ++m) {
    const double value = grid_values[m];
    const bool left_ok = m == 0 || value >= grid_values[m - 1];
    const bool right_ok = m == 2 * half || value > grid_values[m + 1];
    if (!(left_ok && right_ok)) continue;
    if (value > best_value) {
      second_value = best_value;
      best_value = value;
      best = m;
    } else if (value > second_value) {
      second_value = value;
    }
    if (peak_count_ > 1 && value > 0.0) {
      int position = top_count;
      while (position > 0 && top_value[static_cast<std::size_t>(position - 1)] < value) --position;
      if (position >= peak_count_) continue;
      for (int moved = std::min(top_count, peak_count_ - 1); moved > position; --moved) {
        top_index[static_cast<std::size_t>(moved)] = top_index[static_cast<std::size_t>(moved - 1)];
        top_value[static_cast<std::size_t>(moved)] = top_value[static_cast<std::size_t>(moved - 1)];
      }
      top_index[static_cast<std::size_t>(position)] = m;
      top_value[static_cast<std::size_t>(position)] = value;
      top_count = std::min(top_count + 1, peak_count_);
    }
  }
  if (best < 0 || !(best_value > 0.0)) return;
  const double start_lag = (best - half) * lag_step_s_;
  if (!refine(static_cast<int>(p), start_lag, result.peak)) {
    result.peak = {start_lag, best_value};
  }
  const double limit = pairs_[p].max_lag_s + 1.0 / sample_rate_hz_;
  result.peak.lag_s = std::clamp(result.peak.lag_s, -limit, limit);
  result.second_value = std::max(second_value, 0.0);
  result.peak_ratio = result.second_value > result.peak.value / kMaxPeakRatio
                          ? result.peak.value / result.second_value
                          : kMaxPeakRatio;
  result.coherence = result.peak.coherence;
  result.tdoa_variance_s2 = tdoa_variance_for_peak(result.peak.value);
  result.peaks[0] = result.peak;
  result.peak_count = 1;
  // The further peaks (the first is `best`), refined without refine()'s one-per-pair cache,
  // which keeps the main peak's answer for the trackers. Two grid maxima that refine to one
  // peak count once.
  for (int k = 1; k < top_count; ++k) {
    const int m = top_index[static_cast<std::size_t>(k)];
    GccPeak further;
    const bool refined = interpolation_ == LagInterpolation::band_limited
                             ? refine_band_limited(static_cast<int>(p), m, further)
                             : refine_parabolic(static_cast<int>(p), m, further);
    if (!refined) further = {(m - half) * lag_step_s_, top_value[static_cast<std::size_t>(k)]};
    further.lag_s = std::clamp(further.lag_s, -limit, limit);
    if (!(further.value > 0.0)) continue;
    bool distinct = true;
    for (int kept = 0; kept < result.peak_count; ++kept)
      distinct = distinct && std::abs(result.peaks[static_cast<std::size_t>(kept)].lag_s -
                                      further.lag_s) > 0.5 * lag_step_s_;
    if (distinct) result.peaks[static_cast<std::size_t>(result.peak_count++)] = further;
  }
  // Refinement can reorder close values: highest first.
  std::sort(result.peaks.begin() + 1, result.peaks.begin() + result.peak_count,
            [](const GccPeak& a, const GccPeak& b) { return a.value > b.value; });
}

void GccPhat::set_peak_count(int count) {
  if (count < 1 || count > kMaxGccPeaks)
    throw std::invalid_argument("peak count must be in [1, " + std::to_string(kMaxGccPeaks) +
                                "], got " + std::to_string(count));
  peak_count_ = count;
}

double GccPhat::tdoa_variance_for_peak(double peak_value) const {
  // A peak value rho = mean_k cos(phase error_k) ~ exp(-sigma_phi^2 / 2): the mean phase-noise
  // variance per bin. A least-squares phase slope through the origin over the band then has
  // variance sigma_phi^2 / sum w_k^2, times the number of bins sharing one independent phase.
  const double rho = std::clamp(peak_value, 0.02, 0.999);
  const double phase_variance = -2.0 * std::log(rho);
  // Weighted: the phase slope through the origin has variance
  // sigma^2 sum w^2 w_k^2 / (sum w w_k^2)^2 (sigma^2 / sum w_k^2 when every w is 1).
  return bin_correlation_ * phase_variance * kept_sum_w2_omega2_ /
         (kept_sum_omega2_ * kept_sum_omega2_);
}

bool GccPhat::refine(int pair, double start_lag_s, GccPeak& out) const {
  const int m = climb(pair, start_lag_s);
  // The same grid maximum gives the same refined peak: the trackers, the static null and SRP
  // ask again for peaks correlate() already refined.
  const auto p = static_cast<std::size_t>(pair);
  if (refined_index_[p] == m) {
    out = refined_peaks_[p];
    return refined_ok_[p] != 0;
  }
  const bool ok = interpolation_ == LagInterpolation::band_limited
                      ? refine_band_limited(pair, m, out)
                      : refine_parabolic(pair, m, out);
  refined_index_[p] = m;
  refined_peaks_[p] = out;
  refined_ok_[p] = ok ? 1 : 0;
  return ok;
}

int GccPhat::climb(int pair, double start_lag_s) const {
  const std::span<const double> values = grid(pair);
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  int m = static_cast<int>(std::lround(start_lag_s / lag_step_s_)) + half;
  m = std::clamp(m, 0, 2 * half);
  for (int guard = 0; guard < 2 * half + 1; ++guard) {
    if (m > 0 && values[static_cast<std::size_t>(m - 1)] > values[static_cast<std::size_t>(m)]) {
      --m;
    } else if (m < 2 * half &&
               values[static_cast<std::size_t>(m + 1)] > values[static_cast<std::size_t>(m)]) {
      ++m;
    } else {
      break;
    }
  }
  return m;
}

bool GccPhat::refine_parabolic(int pair, int m, GccPeak& out) const {
  refine_parabolic_grid_only(pair, m, out);
  double unused = 0.0;
  evaluate(pair, out.lag_s, unused, out.coherence);
  return true;
}

bool GccPhat::refine_band_limited(int pair, int m, GccPeak& out) const {
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  const double grid_lag_s = (m - half) * lag_step_s_;
  // Start from the parabola through the grid maximum: within a fraction of a grid step, so
  // Newton (quadratic convergence) needs one or two passes over the band.
  GccPeak start;
  refine_parabolic_grid_only(pair, m, start);
  const int found = newton_peak(pair, start.lag_s, grid_lag_s, out);
  if (found < 0) return refine_parabolic(pair, m, out);
  return found > 0;
}

bool GccPhat::refine_from(int pair, double start_lag_s, GccPeak& out) {
  if (!prepared_) {
    prepare(weights_applied_);
    // The grids are of another mask: no answer of theirs stands.
    for (PairCorrelation& result : results_) result = PairCorrelation{};
  }
  return enough_bins_ && newton_peak(pair, start_lag_s, start_lag_s, out) > 0;
}

int GccPhat::newton_peak(int pair, double start_lag_s, double anchor_lag_s, GccPeak& out) const {
  double lag = start_lag_s;
  const std::size_t offset = static_cast<std::size_t>(pair) * static_cast<std::size_t>(band_bins_);
  const std::complex<double>* phasor = phasors_.data() + offset;
  const double* magnitude = magnitudes_.data() + offset;
  // R(tau) = sum Re(W_k e^{j w_k tau}); its n-th derivative is sum w_k^n Re(j^n W_k e^{..}).
  // One pass over the band gives R and its first four derivatives at the current lag (and the
  // |G|-weighted sum with two), i.e. R's Taylor polynomial; the peak of that polynomial is
  // found without touching the band again. The polynomial's R' is off by at most
  // |R^(5)| d^4 / 24 <= w_top sum_kept w^4 d^4 / 24 (|W_k| <= 1), so the peak by that over R'':
  // below kNewtonResidual_s the pass was the last (from the parabola's start, typically the
  // first), else the next pass starts from there.
  for (int iteration = 0; iteration < 6; ++iteration) {
    const simd::TaylorSums sums =
        simd::taylor_sums({runs_.data(), runs_.size(), bin_omega_, phasor, magnitude, lag});
    const double r0 = sums.r[0];
    const double r1 = sums.r[1];
    const double r2 = sums.r[2];
    const double r3 = sums.r[3];
    const double r4 = sums.r[4];
    if (!(r2 < 0.0)) return -1;
    // Newton on the polynomial's R' = r1 + r2 d + r3 d^2/2 + r4 d^3/6, from the plain step.
    const double reach = 0.5 * lag_step_s_;
    double delta = std::clamp(-r1 / r2, -reach, reach);
    double curvature = r2;
    for (int polish = 0; polish < 4; ++polish) {
      const double slope_at = r1 + delta * (r2 + delta * (0.5 * r3 + delta * r4 / 6.0));
      curvature = r2 + delta * (r3 + 0.5 * delta * r4);
      if (!(curvature < 0.0)) {
        curvature = r2;
        delta = std::clamp(-r1 / r2, -reach, reach);
        break;
      }
      delta = std::clamp(delta - slope_at / curvature, -reach, reach);
    }
    const double delta2 = delta * delta;
    const double residual_s = taylor_bound_ * delta2 * delta2 / (24.0 * std::abs(curvature));
    lag += delta;
    if (residual_s < kNewtonResidual_s || iteration == 5) {
      if (std::abs(lag - anchor_lag_s) > 1.5 * lag_step_s_) return 0;
      const double total = magnitude_sums_[static_cast<std::size_t>(pair)];
      const double value =
          r0 + delta * (r1 + delta * (0.5 * r2 + delta * (r3 / 6.0 + delta * r4 / 24.0)));
      const double coherent = sums.weighted + delta * sums.slope + 0.5 * delta2 * sums.bend;
      out = {lag, value / kept_weight_, total > 0.0 ? std::clamp(coherent / total, 0.0, 1.0) : 0.0};
      return 1;
    }
  }
  return 0;
}

void GccPhat::refine_parabolic_grid_only(int pair, int m, GccPeak& out) const {
  const std::span<const double> values = grid(pair);
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  double offset = 0.0;
  double value = values[static_cast<std::size_t>(m)];
  if (m > 0 && m < 2 * half) {
    const double left = values[static_cast<std::size_t>(m - 1)];
    const double right = values[static_cast<std::size_t>(m + 1)];
    const double curvature = left - 2.0 * value + right;
    if (curvature < 0.0) {
      offset = std::clamp(0.5 * (left - right) / curvature, -0.5, 0.5);
      value -= 0.25 * (left - right) * offset;
    }
  }
  out = {(m - half + offset) * lag_step_s_, value, 0.0};
}

int GccPhat::top_peaks(int pair, std::span<GccPeak> out) const {
  const std::span<const double> values = grid(pair);
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  int count = 0;
  for (int m = 0; m < 2 * half + 1; ++m) {
    const double value = values[static_cast<std::size_t>(m)];
    const bool left_ok = m == 0 || value >= values[static_cast<std::size_t>(m - 1)];
    const bool right_ok = m == 2 * half || value > values[static_cast<std::size_t>(m + 1)];
    if (!(left_ok && right_ok) || !(value > 0.0)) continue;
    // Insertion into the descending list of at most out.size().
    int position = count;
    while (position > 0 && out[static_cast<std::size_t>(position - 1)].value < value) --position;
    if (position >= static_cast<int>(out.size())) continue;
    const int last = std::min(count, static_cast<int>(out.size()) - 1);
    for (int moved = last; moved > position; --moved)
      out[static_cast<std::size_t>(moved)] = out[static_cast<std::size_t>(moved - 1)];
    out[static_cast<std::size_t>(position)] = {(m - half) * lag_step_s_, value};
    count = std::min(count + 1, static_cast<int>(out.size()));
  }
  return count;
}

}  // namespace dronetrack::doa
