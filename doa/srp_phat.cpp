#include "doa/srp_phat.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include <Eigen/Eigenvalues>

namespace dronetrack::doa {

namespace {
// Directions per patch of the bounded search: small patches have tight bounds, many patches
// cost more bounds per look; 16 is near the minimum of the sum for a 5 deg grid. A patch whose
// bound passes is searched group by group, each group (~4 neighbouring directions) under its
// own, tighter bound: most of a passing patch's directions are on the slope of a peak, below
// the best found.
constexpr int kDirectionsPerPatch = 16;
constexpr int kDirectionsPerGroup = 4;
// An interpolated value may exceed the larger of its two grid values by a rounding error.
constexpr double kBoundMargin = 1e-9;

// Fibonacci sphere: `count` nearly uniform unit vectors.
Eigen::Vector3d fibonacci_direction(int n, int count) {
  const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
  const double z = 1.0 - 2.0 * (n + 0.5) / count;
  const double radius = std::sqrt(std::max(0.0, 1.0 - z * z));
  return {radius * std::cos(golden_angle * n), radius * std::sin(golden_angle * n), z};
}

// The nearest of the Fibonacci centres fibonacci_direction(c, centres.size()) to a unit
// direction, the lowest index among equals. Centre c sits at z = 1 - 2 (c + 0.5) / count and two
// unit vectors' z differ by no more than their angle, so only centres within the lattice's
// covering radius in z can be nearest: twice the mean spacing is well beyond it (start-up: a
// third of the centres looked at).
std::size_t nearest(const Eigen::Vector3d& direction, const std::vector<Eigen::Vector3d>& centres) {
  const auto count = static_cast<double>(centres.size());
  const double reach = 2.0 * std::sqrt(4.0 * std::numbers::pi / count);
  auto index_at = [count](double z) {
    return std::clamp((1.0 - z) * count / 2.0 - 0.5, 0.0, count - 1.0);
  };
  const auto first = static_cast<std::size_t>(std::floor(index_at(direction.z() + reach)));
  const auto last = static_cast<std::size_t>(std::ceil(index_at(direction.z() - reach)));
  std::size_t nearest_centre = first;
  double nearest_cosine = -2.0;
  for (std::size_t c = first; c <= last; ++c) {
    const double cosine = direction.dot(centres[c]);
    if (cosine > nearest_cosine) {
      nearest_cosine = cosine;
      nearest_centre = c;
    }
  }
  return nearest_centre;
}
}  // namespace

SrpPhat::SrpPhat(const LsDoaSolver& solver, const GccPhat& gcc, double grid_deg)
    : solver_(&solver), pairs_(gcc.pair_count()) {
  if (!(grid_deg >= 0.5 && grid_deg <= 30.0))
    throw std::invalid_argument("srp_grid_deg must be in [0.5, 30]");
  const double spacing_rad = grid_deg * std::numbers::pi / 180.0;
  const int count =
      static_cast<int>(std::ceil(4.0 * std::numbers::pi / (spacing_rad * spacing_rad)));
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
    const Eigen::Vector3d direction = fibonacci_direction(n, count);
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
  for (int p = 0; p < pairs_; ++p) grid_last_.push_back(2 * gcc.half_span(p));
  residual_.assign(static_cast<std::size_t>(grid_stride_) * static_cast<std::size_t>(pairs_), 0.0);
  range_levels_ = std::bit_width(static_cast<unsigned>(grid_stride_));
  range_maxima_.assign(residual_.size() * static_cast<std::size_t>(range_levels_), 0.0);
  group_directions();
}

void SrpPhat::group_directions() {
  // Groups: each direction joins its nearest centre of a coarser Fibonacci sphere; patches: each
  // group joins (by its centre) the nearest centre of a coarser one still, so every patch is a
  // union of whole groups.
  const int sphere_share = solver_->rank() == 2 ? 2 : 1;  // the hemisphere's centres are half
  auto centres = [&](int directions_per_centre) {
    const int count =
        std::max(1, static_cast<int>(directions_.size()) / directions_per_centre * sphere_share);
    std::vector<Eigen::Vector3d> out;
    for (int c = 0; c < count; ++c) out.push_back(fibonacci_direction(c, count));
    return out;
  };
  const std::vector<Eigen::Vector3d> group_centres = centres(kDirectionsPerGroup);
  const std::vector<Eigen::Vector3d> patch_centres = centres(kDirectionsPerPatch);
  std::vector<std::vector<std::int32_t>> groups(group_centres.size());
  for (std::size_t d = 0; d < directions_.size(); ++d)
    groups[nearest(directions_[d], group_centres)].push_back(static_cast<std::int32_t>(d));
  std::vector<std::vector<std::size_t>> patches(patch_centres.size());  // their groups
  for (std::size_t c = 0; c < groups.size(); ++c)
    if (!groups[c].empty()) patches[nearest(group_centres[c], patch_centres)].push_back(c);
  patch_offsets_.assign(1, 0);
  group_offsets_.assign(1, 0);
  for (const std::vector<std::size_t>& patch : patches) {
    if (patch.empty()) continue;
    const std::size_t patch_first_member = members_.size();
    for (const std::size_t c : patch) {
      members_.insert(members_.end(), groups[c].begin(), groups[c].end());
      group_offsets_.push_back(static_cast<std::int32_t>(members_.size()));
      append_range_positions(groups[c], group_low_, group_high_);
    }
    patch_offsets_.push_back(static_cast<std::int32_t>(group_offsets_.size() - 1));
    append_range_positions(std::span<const std::int32_t>(members_).subspan(patch_first_member),
                           patch_low_, patch_high_);
  }
  patch_bounds_.assign(patch_offsets_.size() - 1, 0.0);
}

// Per pair, the two entries of the sparse table whose larger is the range maximum over the lags
// the members' interpolations read: their positions are fixed, so they are found once here.
void SrpPhat::append_range_positions(std::span<const std::int32_t> members,
                                     std::vector<std::int32_t>& low,
                                     std::vector<std::int32_t>& high) const {
  const auto stride = static_cast<std::size_t>(grid_stride_);
  for (int p = 0; p < pairs_; ++p) {
    std::int32_t first = std::numeric_limits<std::int32_t>::max();
    std::int32_t last = 0;
    for (const std::int32_t d : members) {
      const std::int32_t below =
          lag_index_[static_cast<std::size_t>(d) * static_cast<std::size_t>(pairs_) +
                     static_cast<std::size_t>(p)];
      first = std::min(first, below);
      last = std::max(last, below + 1);
    }
    const int l = std::bit_width(static_cast<unsigned>(last - first + 1)) - 1;
    const std::size_t level =
        (static_cast<std::size_t>(p) * static_cast<std::size_t>(range_levels_) +
         static_cast<std::size_t>(l)) *
        stride;
    low.push_back(static_cast<std::int32_t>(level + static_cast<std::size_t>(first)));
    high.push_back(
        static_cast<std::int32_t>(level + static_cast<std::size_t>(last - (1 << l) + 1)));
  }
}

double SrpPhat::bound(const std::vector<std::int32_t>& low, const std::vector<std::int32_t>& high,
                      std::size_t index) const {
  double sum = kBoundMargin;
  for (int p = 0; p < pairs_; ++p) {
    const std::size_t at = index * static_cast<std::size_t>(pairs_) + static_cast<std::size_t>(p);
    sum += std::max(range_maxima_[static_cast<std::size_t>(low[at])],
                    range_maxima_[static_cast<std::size_t>(high[at])]);
  }
  return sum;
}

void SrpPhat::build_range_maxima() const {
  const auto stride = static_cast<std::size_t>(grid_stride_);
  for (int p = 0; p < pairs_; ++p) {
    double* level = range_maxima_.data() +
                    static_cast<std::size_t>(p) * static_cast<std::size_t>(range_levels_) * stride;
    std::copy_n(residual_.data() + static_cast<std::size_t>(p) * stride, stride, level);
    for (int l = 1; l < range_levels_; ++l) {
      const double* previous = level;
      level += stride;
      const std::size_t half = std::size_t{1} << (l - 1);
      for (std::size_t m = 0; m + 2 * half <= stride; ++m)
        level[m] = std::max(previous[m], previous[m + half]);
    }
  }
  range_maxima_stale_ = false;
}

void SrpPhat::begin_frame(const GccPhat& gcc) {
  range_maxima_stale_ = true;
  for (int p = 0; p < pairs_; ++p) {
    const std::span<const double> grid = gcc.grid(p);
    std::copy(grid.begin(), grid.end(),
              residual_.begin() + static_cast<std::ptrdiff_t>(p) * grid_stride_);
  }
}

void SrpPhat::subtract_direction(const GccPhat& gcc, const Eigen::Vector3d& direction_array) {
  range_maxima_stale_ = true;
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

double SrpPhat::power_sum(std::size_t direction) const {
  double sum = 0.0;
  for (int p = 0; p < pairs_; ++p) {
    const std::size_t at =
        direction * static_cast<std::size_t>(pairs_) + static_cast<std::size_t>(p);
    const double* residual = residual_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_;
    const double fraction = lag_fraction_[at];
    const auto below = static_cast<std::size_t>(lag_index_[at]);
    sum += residual[below] * (1.0 - fraction) + residual[below + 1] * fraction;
  }
  return sum;
}

bool SrpPhat::strongest_exhaustive(SrpPeak& out) const {
  std::size_t best = directions_.size();
  double best_power = 0.0;
  for (std::size_t d = 0; d < directions_.size(); ++d) {
    const double sum = power_sum(d);
    if (sum > best_power) {
      best_power = sum;
      best = d;
    }
  }
  if (best == directions_.size()) return false;
  out = {directions_[best], best_power / pairs_};
  return true;
}

bool SrpPhat::strongest(SrpPeak& out) const { return strongest(out, 0.0); }

bool SrpPhat::strongest(SrpPeak& out, double min_power) const {
  // Sums over pairs below this cannot reach min_power (the margin covers rounding).
  const double floor_sum = min_power * pairs_ - kBoundMargin;
  // Every pair's highest value anywhere, straight from the residual: when even their sum
  // cannot reach the floor (a look after the sources are found, usually), the range-maximum
  // table is not built at all.
  double everywhere_bound = kBoundMargin;
  for (int p = 0; p < pairs_; ++p) {
    const double* residual = residual_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_;
    everywhere_bound +=
        *std::max_element(residual, residual + grid_last_[static_cast<std::size_t>(p)] + 1);
  }
  if (everywhere_bound < floor_sum || !(everywhere_bound > 0.0)) return false;
  if (range_maxima_stale_) build_range_maxima();
  const std::size_t patches = patch_bounds_.size();
  std::size_t most_promising = 0;
  for (std::size_t g = 0; g < patches; ++g) {
    patch_bounds_[g] = bound(patch_low_, patch_high_, g);
    if (patch_bounds_[g] > patch_bounds_[most_promising]) most_promising = g;
  }
  if (patch_bounds_[most_promising] < floor_sum) return false;
  // Same answer as visiting every direction in order: the highest power, and among equal
  // powers the lowest direction index. A bound equal to the best may still hide an equal power
  // at a lower index: only a bound below it is skipped.
  std::size_t best = directions_.size();
  double best_power = 0.0;
  auto visit = [&](std::size_t g) {
    for (auto q = patch_offsets_[g]; q < patch_offsets_[g + 1]; ++q) {
      const auto group = static_cast<std::size_t>(q);
      if (bound(group_low_, group_high_, group) < std::max(best_power, floor_sum)) continue;
      for (auto m = group_offsets_[group]; m < group_offsets_[group + 1]; ++m) {
        const auto d = static_cast<std::size_t>(members_[static_cast<std::size_t>(m)]);
        const double sum = power_sum(d);
        if (sum > best_power || (sum == best_power && best < directions_.size() && d < best)) {
          best_power = sum;
          best = d;
        }
      }
    }
  };
  // The most promising patch first: its best power then rules out most others.
  visit(most_promising);
  for (std::size_t g = 0; g < patches; ++g) {
    if (g == most_promising || patch_bounds_[g] < std::max(best_power, floor_sum)) continue;
    visit(g);
  }
  if (best == directions_.size() || best_power / pairs_ < min_power) return false;
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
