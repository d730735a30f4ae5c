#include "doa/srp_phat.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <Eigen/Eigenvalues>

namespace dronetrack::doa {

SrpPhat::SrpPhat(const LsDoaSolver& solver, const GccPhat& gcc, double grid_deg)
    : solver_(&solver), pairs_(gcc.pair_count()) {
  if (!(grid_deg >= 0.5 && grid_deg <= 30.0))
    throw std::invalid_argument("srp_grid_deg must be in [0.5, 30]");
  const double spacing_rad = grid_deg * std::numbers::pi / 180.0;
  const int count =
      static_cast<int>(std::ceil(4.0 * std::numbers::pi / (spacing_rad * spacing_rad)));
  const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
  const bool hemisphere = solver.rank() == 2;
  // For planar arrays, "up" is the array plane's normal (the third principal axis).
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  if (hemisphere) {
    // The solver's basis is not exposed; the plane normal is orthogonal to every pair vector.
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (int p = 0; p < pairs_; ++p) {
      Eigen::Vector3d tdoas;
      for (int axis = 0; axis < 3; ++axis)
        tdoas(axis) = solver.tdoa_for_direction(p, Eigen::Vector3d::Unit(axis));
      scatter += tdoas * tdoas.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
    normal = eigen.eigenvectors().col(0);
  }
  directions_.reserve(static_cast<std::size_t>(count));
  for (int n = 0; n < count; ++n) {
    const double z = 1.0 - 2.0 * (n + 0.5) / count;
    const double radius = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Eigen::Vector3d direction(radius * std::cos(golden_angle * n),
                                    radius * std::sin(golden_angle * n), z);
    if (hemisphere && direction.dot(normal) < 0.0) continue;
    directions_.push_back(direction);
  }
  const double step = gcc.lag_step_s();
  lag_index_.resize(directions_.size() * static_cast<std::size_t>(pairs_));
  lag_fraction_.resize(lag_index_.size());
  for (std::size_t d = 0; d < directions_.size(); ++d) {
    for (int p = 0; p < pairs_; ++p) {
      const int half = gcc.half_span(p);
      const double position = solver.tdoa_for_direction(p, directions_[d]) / step + half;
      const int below = std::clamp(static_cast<int>(std::floor(position)), 0, 2 * half - 1);
      lag_index_[d * static_cast<std::size_t>(pairs_) + static_cast<std::size_t>(p)] = below;
      lag_fraction_[d * static_cast<std::size_t>(pairs_) + static_cast<std::size_t>(p)] =
          static_cast<float>(std::clamp(position - below, 0.0, 1.0));
    }
  }
  int max_half_span = 0;
  for (int p = 0; p < pairs_; ++p) max_half_span = std::max(max_half_span, gcc.half_span(p));
  grid_stride_ = 2 * max_half_span + 1;
  residual_.assign(static_cast<std::size_t>(grid_stride_) * static_cast<std::size_t>(pairs_), 0.0);
}

void SrpPhat::begin_frame(const GccPhat& gcc) {
  for (int p = 0; p < pairs_; ++p) {
    const std::span<const double> grid = gcc.grid(p);
    std::copy(grid.begin(), grid.end(),
              residual_.begin() + static_cast<std::ptrdiff_t>(p) * grid_stride_);
  }
}

void SrpPhat::subtract(const GccPhat& gcc, std::span<const PairTdoa> tdoas) {
  const double step = gcc.lag_step_s();
  for (int p = 0; p < pairs_; ++p) {
    const PairTdoa& tdoa = tdoas[static_cast<std::size_t>(p)];
    if (!(tdoa.variance_s2 > 0.0)) continue;
    const int half = gcc.half_span(p);
    double* residual = residual_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_;
    for (int m = 0; m <= 2 * half; ++m)
      residual[m] -= tdoa.peak_value * gcc.phat_kernel((m - half) * step - tdoa.tdoa_s);
  }
}

void SrpPhat::subtract_direction(const GccPhat& gcc, const Eigen::Vector3d& direction_array) {
  const double step = gcc.lag_step_s();
  for (int p = 0; p < pairs_; ++p) {
    const int half = gcc.half_span(p);
    double* residual = residual_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_;
    const double lag = solver_->tdoa_for_direction(p, direction_array);
    const double position = std::clamp(lag / step + half, 0.0, 2.0 * half);
    const int below = std::min(static_cast<int>(position), 2 * half - 1);
    const double fraction = position - below;
    const double value =
        std::max(0.0, residual[below] * (1.0 - fraction) + residual[below + 1] * fraction);
    for (int m = 0; m <= 2 * half; ++m)
      residual[m] -= value * gcc.phat_kernel((m - half) * step - lag);
  }
}

bool SrpPhat::strongest(SrpPeak& out) const {
  std::size_t best = directions_.size();
  double best_power = 0.0;
  for (std::size_t d = 0; d < directions_.size(); ++d) {
    double sum = 0.0;
    for (int p = 0; p < pairs_; ++p) {
      const std::size_t at = d * static_cast<std::size_t>(pairs_) + static_cast<std::size_t>(p);
      const double* residual = residual_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_;
      const double fraction = lag_fraction_[at];
      const auto below = static_cast<std::size_t>(lag_index_[at]);
      sum += residual[below] * (1.0 - fraction) + residual[below + 1] * fraction;
    }
    if (sum > best_power) {
      best_power = sum;
      best = d;
    }
  }
  if (best == directions_.size()) return false;
  out = {directions_[best], best_power / pairs_};
  return true;
}

void SrpPhat::tdoas_near(const GccPhat& gcc, const Eigen::Vector3d& direction_array,
                         std::span<PairTdoa> out) const {
  for (int p = 0; p < pairs_; ++p) {
    const double lag = solver_->tdoa_for_direction(p, direction_array);
    GccPeak peak;
    out[static_cast<std::size_t>(p)] =
        gcc.refine(p, lag, peak) && peak.value > 0.0
            ? PairTdoa{peak.lag_s, gcc.tdoa_variance_for_peak(peak.value), peak.value,
                       peak.coherence}
            : PairTdoa{};
  }
}

}  // namespace dronetrack::doa
