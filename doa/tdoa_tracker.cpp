#include "doa/tdoa_tracker.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include <Eigen/Core>

#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

PairTdoa from_peak(const GccPhat& gcc, const GccPeak& peak) {
  return {peak.lag_s, gcc.tdoa_variance_for_peak(peak.value), peak.value, peak.coherence};
}

class PerFrameEstimator final : public TdoaEstimator {
 public:
  void update(double, const GccPhat& gcc, bool signal_present, std::span<PairTdoa> out) override {
    for (int p = 0; p < gcc.pair_count(); ++p) {
      const PairCorrelation& pair = gcc.pair(p);
      out[static_cast<std::size_t>(p)] =
          signal_present && pair.peak.value > 0.0
              ? PairTdoa{pair.peak.lag_s, pair.tdoa_variance_s2, pair.peak.value, pair.coherence}
              : PairTdoa{};
    }
  }
};

// Bayesian filter over each pair's lag grid; the likelihood decides between the seed-000 form
// (whole correlation) and the seed-004 form (top K peaks).
class GridEstimator final : public TdoaEstimator {
 public:
  GridEstimator(const GccPhat& gcc, const TdoaTrackerSettings& settings, bool multi_peak)
      : settings_(settings), multi_peak_(multi_peak) {
    const double step = gcc.lag_step_s();
    for (int p = 0; p < gcc.pair_count(); ++p) {
      const int size = 2 * gcc.half_span(p) + 1;
      posteriors_.emplace_back(static_cast<std::size_t>(size), 1.0 / size);
      scratch_.emplace_back(static_cast<std::size_t>(size), 0.0);
      // TDOA rate bound: |d tau / dt| <= (|p_i - p_j| / c) * angular rate.
      const double sigma_steps =
          std::max(0.5, gcc.pair_spec(p).max_lag_s * settings.max_angular_rate_dps * kDegToRad *
                            settings.hop_s / step);
      const int reach = static_cast<int>(std::ceil(3.0 * sigma_steps));
      std::vector<double> kernel(static_cast<std::size_t>(2 * reach + 1));
      double total = 0.0;
      for (int d = -reach; d <= reach; ++d) {
        const double value = std::exp(-0.5 * d * d / (sigma_steps * sigma_steps));
        kernel[static_cast<std::size_t>(d + reach)] = value;
        total += value;
      }
      for (double& value : kernel) value /= total;
      kernels_.push_back(std::move(kernel));
    }
    peaks_.resize(static_cast<std::size_t>(std::max(1, settings.multi_peak_count)));
  }

  void update(double, const GccPhat& gcc, bool signal_present, std::span<PairTdoa> out) override {
    const double step = gcc.lag_step_s();
    for (int p = 0; p < gcc.pair_count(); ++p) {
      std::vector<double>& posterior = posteriors_[static_cast<std::size_t>(p)];
      std::vector<double>& predicted = scratch_[static_cast<std::size_t>(p)];
      predict(kernels_[static_cast<std::size_t>(p)], posterior, predicted);
      const int size = static_cast<int>(posterior.size());
      const int half = (size - 1) / 2;
      out[static_cast<std::size_t>(p)] = PairTdoa{};
      if (!signal_present) {
        posterior.swap(predicted);
        continue;
      }
      const std::span<const double> grid = gcc.grid(p);
      int peak_count = 0;
      if (multi_peak_) peak_count = gcc.top_peaks(p, peaks_);
      double total = 0.0;
      for (int m = 0; m < size; ++m) {
        double likelihood = settings_.likelihood_floor;
        if (multi_peak_) {
          for (int k = 0; k < peak_count; ++k) {
            const double distance = (m - half) - peaks_[static_cast<std::size_t>(k)].lag_s / step;
            likelihood += sharpen(peaks_[static_cast<std::size_t>(k)].value) *
                          std::exp(-0.5 * distance * distance);
          }
        } else {
          likelihood += sharpen(std::max(grid[static_cast<std::size_t>(m)], 0.0));
        }
        posterior[static_cast<std::size_t>(m)] =
            predicted[static_cast<std::size_t>(m)] * likelihood;
        total += posterior[static_cast<std::size_t>(m)];
      }
      if (!(total > 0.0) || !std::isfinite(total)) {
        std::fill(posterior.begin(), posterior.end(), 1.0 / size);
        continue;
      }
      int map_index = 0;
      for (int m = 0; m < size; ++m) {
        posterior[static_cast<std::size_t>(m)] /= total;
        if (posterior[static_cast<std::size_t>(m)] > posterior[static_cast<std::size_t>(map_index)])
          map_index = m;
      }
      GccPeak refined;
      const double map_lag = (map_index - half) * step;
      const PairCorrelation& pair = gcc.pair(p);
      if (std::abs(pair.peak.lag_s - map_lag) <= 1.5 * step && pair.peak.value > 0.0) {
        // The MAP is this frame's highest peak: already refined.
        out[static_cast<std::size_t>(p)] = from_peak(gcc, pair.peak);
      } else if (gcc.refine(p, map_lag, refined) && refined.value > 0.0) {
        // The MAP lobe must hold a correlation maximum in this frame (not just the prior).
        const double limit = gcc.pair_spec(p).max_lag_s + step;
        if (std::abs(refined.lag_s) <= limit && std::abs(refined.lag_s - map_lag) <= 2.0 * step)
          out[static_cast<std::size_t>(p)] = from_peak(gcc, refined);
      }
    }
  }

 private:
  // value^sharpness; the default 4 without pow(), which is most of the filter's cost.
  double sharpen(double value) const {
    if (settings_.likelihood_sharpness == 4.0) {
      const double squared = value * value;
      return squared * squared;
    }
    return std::pow(value, settings_.likelihood_sharpness);
  }

  void predict(const std::vector<double>& kernel, const std::vector<double>& prior,
               std::vector<double>& predicted) const {
    const int size = static_cast<int>(prior.size());
    const int reach = (static_cast<int>(kernel.size()) - 1) / 2;
    // A little uniform mass lets the filter re-acquire a source that jumped (a new drone).
    constexpr double kMixing = 1e-3;
    for (int m = 0; m < size; ++m) {
      double sum = 0.0;
      double weight = 0.0;
      for (int d = -reach; d <= reach; ++d) {
        const int source = m - d;
        if (source < 0 || source >= size) continue;
        sum +=
            kernel[static_cast<std::size_t>(d + reach)] * prior[static_cast<std::size_t>(source)];
        weight += kernel[static_cast<std::size_t>(d + reach)];
      }
      predicted[static_cast<std::size_t>(m)] = (1.0 - kMixing) * sum / weight + kMixing / size;
    }
  }

  TdoaTrackerSettings settings_;
  bool multi_peak_;
  std::vector<std::vector<double>> posteriors_;
  std::vector<std::vector<double>> scratch_;
  std::vector<std::vector<double>> kernels_;
  std::vector<GccPeak> peaks_;
};

}  // namespace

TdoaRegression::TdoaRegression(int pair_count, const TdoaTrackerSettings& settings)
    : settings_(settings),
      window_(static_cast<std::size_t>(std::max(4, settings.regression_window_frames))) {
  delay_s_ = std::max(0, settings.regression_delay_frames) * settings.hop_s;
  max_age_s_ = (static_cast<double>(window_) + 0.5) * settings.hop_s;
  histories_.resize(static_cast<std::size_t>(pair_count));
  for (History& history : histories_) history.points.resize(window_);
  residuals_.resize(window_);
  sorted_.resize(window_);
  weights_.resize(window_);
}

void TdoaRegression::clear() {
  for (History& history : histories_) {
    history.next = 0;
    history.count = 0;
  }
}

void TdoaRegression::add(int pair, double time_s, const PairTdoa& tdoa) {
  if (!(tdoa.variance_s2 > 0.0) || !std::isfinite(tdoa.tdoa_s)) return;
  History& history = histories_[static_cast<std::size_t>(pair)];
  history.points[history.next] = {time_s,
                                  tdoa.tdoa_s,
                                  tdoa.variance_s2,
                                  tdoa.peak_value,
                                  1.0 / tdoa.variance_s2,
                                  std::sqrt(tdoa.variance_s2)};
  history.next = (history.next + 1) % window_;
  history.count = std::min(history.count + 1, window_);
}

bool TdoaRegression::fresh(const History& history, std::size_t i, double now_s) const {
  const Point& point = history.points[i];
  return i < history.count && now_s - point.time_s <= max_age_s_ && now_s >= point.time_s &&
         point.variance_s2 > 0.0;
}

// Weighted quadratic in (t - now); returns the coefficients and their covariance.
// The normal matrix of rows (1, dt, dt^2) is the Hankel matrix of the weighted moments
// sum w dt^n, n = 0..4: five sums instead of a 3x3 outer product per point, and its inverse
// in closed form (symmetric adjugate over the determinant) instead of a pivoting LU (this runs
// twice per pair and source every frame). The moments are taken with the weights divided by
// their sum (scale-free cofactors), the covariance scaled back after.
bool TdoaRegression::weighted_fit(const History& history, double now_s,
                                  Eigen::Vector3d& coefficients,
                                  Eigen::Matrix3d& covariance) const {
  double weight_sum = 0.0;
  int used = 0;
  for (std::size_t i = 0; i < window_; ++i) {
    if (weights_[i] <= 0.0) continue;
    weight_sum += weights_[i];
    ++used;
  }
  if (used < 4 || !(weight_sum > 0.0) || !std::isfinite(weight_sum)) return false;
  const double unit = 1.0 / weight_sum;
  double m0 = 0.0, m1 = 0.0, m2 = 0.0, m3 = 0.0, m4 = 0.0;
  double r0 = 0.0, r1 = 0.0, r2 = 0.0;
  for (std::size_t i = 0; i < window_; ++i) {
    if (weights_[i] <= 0.0) continue;
    const double w = weights_[i] * unit;
    const double dt = history.points[i].time_s - now_s;
    const double dt2 = dt * dt;
    const double wy = w * history.points[i].tdoa_s;
    m0 += w;
    m1 += w * dt;
    m2 += w * dt2;
    m3 += w * dt2 * dt;
    m4 += w * dt2 * dt2;
    r0 += wy;
    r1 += wy * dt;
    r2 += wy * dt2;
  }
  // Cofactors of [[m0 m1 m2] [m1 m2 m3] [m2 m3 m4]].
  const double c00 = m2 * m4 - m3 * m3;
  const double c01 = m2 * m3 - m1 * m4;
  const double c02 = m1 * m3 - m2 * m2;
  const double c11 = m0 * m4 - m2 * m2;
  const double c12 = m1 * m2 - m0 * m3;
  const double c22 = m0 * m2 - m1 * m1;
  const double determinant = m0 * c00 + m1 * c01 + m2 * c02;
  // Rank < 3 (fewer than three distinct times): the determinant is rounding next to the
  // product of the diagonal (its bound for a positive definite matrix).
  if (!(determinant > 1e-12 * m0 * m2 * m4)) return false;
  const double scale = unit / determinant;
  covariance << c00 * scale, c01 * scale, c02 * scale, c01 * scale, c11 * scale, c12 * scale,
      c02 * scale, c12 * scale, c22 * scale;
  const double solve = 1.0 / determinant;
  coefficients << (c00 * r0 + c01 * r1 + c02 * r2) * solve,
      (c01 * r0 + c11 * r1 + c12 * r2) * solve, (c02 * r0 + c12 * r1 + c22 * r2) * solve;
  return true;
}

// Zero weight for points whose residual exceeds the gate times the robust spread.
void TdoaRegression::gate_residuals(const History& history) {
  int count = 0;
  for (std::size_t i = 0; i < window_; ++i)
    if (weights_[i] > 0.0) sorted_[static_cast<std::size_t>(count++)] = std::abs(residuals_[i]);
  if (count == 0) return;
  const double mad = simd::middle_value(sorted_.data(), count);
  for (std::size_t i = 0; i < window_; ++i) {
    if (weights_[i] <= 0.0) continue;
    const double scale = std::max(1.4826 * mad, history.points[i].sigma_s);
    if (std::abs(residuals_[i]) > settings_.regression_mad_gate * scale) weights_[i] = 0.0;
  }
}

PairTdoa TdoaRegression::estimate(int pair, double now_s, const PairTdoa& current) {
  const History& history = histories_[static_cast<std::size_t>(pair)];
  int candidates = 0;
  for (std::size_t i = 0; i < window_; ++i) {
    const bool use = fresh(history, i, now_s);
    weights_[i] = use ? history.points[i].inverse_variance : 0.0;
    candidates += use ? 1 : 0;
  }
  // With a delay, the newest frame's own value is not a substitute for the earlier frame's.
  const PairTdoa fallback = delay_s_ > 0.0 ? PairTdoa{} : current;
  if (candidates < 5) return fallback;
  // Only frames that themselves had signal get an estimate (no DOA stamped on a dropout).
  bool target_present = delay_s_ <= 0.0;
  for (std::size_t i = 0; i < window_ && !target_present; ++i)
    target_present = weights_[i] > 0.0 && std::abs(history.points[i].time_s - (now_s - delay_s_)) <
                                              0.5 * settings_.hop_s;
  if (!target_present) return fallback;
  // Start from the median (robust to a minority of outliers, which a least-squares quadratic
  // is not: an outlier at the window's end pulls the curve onto itself), gate on the median
  // absolute deviation, fit, gate again on the fit's residuals, refit.
  int count = 0;
  for (std::size_t i = 0; i < window_; ++i)
    if (weights_[i] > 0.0) sorted_[static_cast<std::size_t>(count++)] = history.points[i].tdoa_s;
  const double level = simd::middle_value(sorted_.data(), count);
  for (std::size_t i = 0; i < window_; ++i)
    residuals_[i] = weights_[i] > 0.0 ? history.points[i].tdoa_s - level : 0.0;
  gate_residuals(history);
  Eigen::Vector3d coefficients;
  Eigen::Matrix3d covariance;
  if (!weighted_fit(history, now_s, coefficients, covariance)) return fallback;
  for (std::size_t i = 0; i < window_; ++i) {
    // Re-admit every fresh point, then gate on the residuals of the fit.
    const Point& point = history.points[i];
    const bool use = fresh(history, i, now_s);
    weights_[i] = use ? point.inverse_variance : 0.0;
    const double dt = point.time_s - now_s;
    residuals_[i] =
        use ? point.tdoa_s - (coefficients(0) + coefficients(1) * dt + coefficients(2) * dt * dt)
            : 0.0;
  }
  gate_residuals(history);
  if (!weighted_fit(history, now_s, coefficients, covariance)) return fallback;
  double chi2 = 0.0;
  int used = 0;
  double peak_sum = 0.0;
  for (std::size_t i = 0; i < window_; ++i) {
    if (weights_[i] <= 0.0) continue;
    const double dt = history.points[i].time_s - now_s;
    const double residual = history.points[i].tdoa_s -
                            (coefficients(0) + coefficients(1) * dt + coefficients(2) * dt * dt);
    chi2 += residual * residual * weights_[i];
    peak_sum += history.points[i].peak_value;
    ++used;
  }
  const double inflation = std::max(1.0, chi2 / std::max(1, used - 3));
  const Eigen::Vector3d at(1.0, -delay_s_, delay_s_ * delay_s_);
  return {coefficients.dot(at),
          at.dot(covariance * at) * inflation * settings_.frame_overlap_variance_factor,
          peak_sum / used, current.coherence};
}

std::unique_ptr<TdoaEstimator> make_tdoa_estimator(TdoaTracker kind, const GccPhat& gcc,
                                                   const TdoaTrackerSettings& settings) {
  switch (kind) {
    case TdoaTracker::per_frame:
      return std::make_unique<PerFrameEstimator>();
    case TdoaTracker::bayesian_grid:
      return std::make_unique<GridEstimator>(gcc, settings, false);
    case TdoaTracker::multi_peak:
      return std::make_unique<GridEstimator>(gcc, settings, true);
    case TdoaTracker::robust_regression:
      // Not a per-pair estimator: the regression runs per source (SourceTracks).
      throw std::invalid_argument(
          "robust_regression smooths each source's TDOAs in SourceTracks, not per pair");
  }
  throw std::invalid_argument("unknown tdoa_tracker");
}

const char* tdoa_tracker_name(TdoaTracker kind) {
  switch (kind) {
    case TdoaTracker::per_frame:
      return "per_frame";
    case TdoaTracker::bayesian_grid:
      return "bayesian_grid";
    case TdoaTracker::multi_peak:
      return "multi_peak";
    case TdoaTracker::robust_regression:
      return "robust_regression";
  }
  return "unknown";
}

}  // namespace dronetrack::doa
