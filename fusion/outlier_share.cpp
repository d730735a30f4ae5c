#include "fusion/outlier_share.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace dronetrack::fusion {
namespace {
// e stays inside (0, kMaxShare]: the mixture needs e < 1, and the config bounds its prior by 0.9.
constexpr double kMinShare = 1e-9;
constexpr double kMaxShare = 0.9;
// Newton steps per refresh: the window moves by a few DOAs per frame, so the previous maximum is
// close and one or two steps reach it; the rest are for the first frames after a jump.
constexpr int kMaxSteps = 6;
constexpr double kTolerance = 1e-7;
}  // namespace

OutlierShareEstimate::OutlierShareEstimate(double prior_share, double prior_doas, int window_doas)
    : prior_outliers_(prior_doas * prior_share),
      prior_inliers_(prior_doas * (1.0 - prior_share)),
      ratio_(static_cast<std::size_t>(std::max(window_doas, 1)), 1.0),
      share_(std::clamp(prior_share, kMinShare, kMaxShare)) {
  if (!(prior_share >= 0.0 && prior_share < 1.0) || !(prior_doas >= 0.0) || window_doas < 1)
    throw std::invalid_argument("outlier share: prior in [0, 1), prior DOAs >= 0, window >= 1");
}

void OutlierShareEstimate::add(double density_ratio) {
  if (!(density_ratio > 0.0) || !std::isfinite(density_ratio)) return;
  ratio_[static_cast<std::size_t>(next_)] = density_ratio;
  next_ = (next_ + 1) % static_cast<int>(ratio_.size());
  count_ = std::min(count_ + 1, static_cast<int>(ratio_.size()));
}

void OutlierShareEstimate::derivatives(double e, double& slope, double& curvature) const {
  slope = prior_outliers_ / e - prior_inliers_ / (1.0 - e);
  curvature = -prior_outliers_ / (e * e) - prior_inliers_ / ((1.0 - e) * (1.0 - e));
  // The filled part of the ring: its order does not matter.
  for (int k = 0; k < count_; ++k) {
    const double g = ratio_[static_cast<std::size_t>(k)];
    const double term = (g - 1.0) / (1.0 - e + e * g);
    slope += term;
    curvature -= term * term;
  }
}

void OutlierShareEstimate::refresh() {
  double e = share_;
  for (int step = 0; step < kMaxSteps; ++step) {
    double slope = 0.0;
    double curvature = 0.0;
    derivatives(e, slope, curvature);
    // At the bound with the slope pointing out of it: the maximum is the bound.
    if ((e <= kMinShare && slope <= 0.0) || (e >= kMaxShare && slope >= 0.0)) break;
    double next = curvature < 0.0 ? e - slope / curvature : (slope > 0.0 ? kMaxShare : kMinShare);
    // Concave, so Newton only overshoots past a bound: go halfway to it instead.
    if (next < kMinShare) next = 0.5 * (e + kMinShare);
    if (next > kMaxShare) next = 0.5 * (e + kMaxShare);
    const bool converged = std::abs(next - e) < kTolerance;
    e = next;
    if (converged) break;
  }
  share_ = std::clamp(e, kMinShare, kMaxShare);
}

}  // namespace dronetrack::fusion
