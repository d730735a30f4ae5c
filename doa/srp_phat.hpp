#pragma once
// Steered-response power (SRP-PHAT) over a direction grid, from the same GCC-PHAT correlations:
// P(d) = mean over pairs of R_p(tau_p(d)). The lag of every pair for every grid direction is
// looked up once at construction (index + fraction into the correlation grid). Several sources
// show as several maxima; each is then refined by the LS solver on the TDOAs of the correlation
// maxima nearest its lags, so a second drone gets the same precision as the first.
//
// The search is exact but does not visit every direction: directions are grouped into small
// patches, and a patch whose upper bound (per pair, the highest correlation over the lags its
// directions touch, summed over pairs) is below the best power found so far is skipped; inside a
// patch that passes, so is each group of ~4 directions under its own bound. The correlation of
// a source is a narrow peak, so a look visits a few patches of ~16 directions and few of their
// groups.
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/gcc_phat.hpp"
#include "doa/ls_doa_solver.hpp"

namespace dronetrack::doa {

struct SrpPeak {
  Eigen::Vector3d direction_array = Eigen::Vector3d::UnitX();
  double power = 0.0;  // mean normalised GCC value over pairs
};

class SrpPhat {
 public:
  // grid_deg: spacing of a Fibonacci grid on the sphere (the upper hemisphere of the array
  // frame's principal plane for planar arrays, whose mirror is ambiguous anyway).
  SrpPhat(const LsDoaSolver& solver, const GccPhat& gcc, double grid_deg);

  // Starts a look from the correlations as they are now (NodePipeline drops the bins of the
  // sources found so far and re-correlates before each further look: SourceBinMask).
  void begin_frame(const GccPhat& gcc);
  // Subtracts what a source at a grid direction explains (its correlation value there times the
  // PHAT kernel around its lags): for a peak no TDOA fit could confirm, so the next look of the
  // same frame does not find it again.
  void subtract_direction(const GccPhat& gcc, const Eigen::Vector3d& direction_array);
  // The strongest direction of what is left; false if nothing positive is left.
  bool strongest(SrpPeak& out) const;
  // The same when its power reaches `min_power` (mean over pairs), else false. The floor only
  // lets the search skip what cannot reach it (after a strong source is cancelled, usually
  // everything): the direction returned is the one strongest(out) returns.
  bool strongest(SrpPeak& out, double min_power) const;
  // The same by visiting every direction (reference for the bounded search; tests, benchmarks).
  bool strongest_exhaustive(SrpPeak& out) const;
  // TDOAs of the correlation maxima nearest a direction's lags: input for LsDoaSolver.
  void tdoas_near(const GccPhat& gcc, const Eigen::Vector3d& direction_array,
                  std::span<PairTdoa> out) const;
  int direction_count() const { return static_cast<int>(directions_.size()); }

 private:
  void group_directions();
  double power_sum(std::size_t direction) const;  // sum over pairs of the interpolated residual
  void build_range_maxima() const;
  void append_range_positions(std::span<const std::int32_t> members, std::vector<std::int32_t>& low,
                              std::vector<std::int32_t>& high) const;
  // Upper bound of the power sum over a patch's or group's directions (range maxima built).
  double bound(const std::vector<std::int32_t>& low, const std::vector<std::int32_t>& high,
               std::size_t index) const;

  const LsDoaSolver* solver_;
  int pairs_;
  std::vector<Eigen::Vector3d> directions_;
  std::vector<std::int32_t> lag_index_;  // directions x pairs: grid index below the lag
  std::vector<float> lag_fraction_;      // directions x pairs
  std::vector<double> residual_;         // pairs x grid_stride_
  int grid_stride_ = 0;
  std::vector<int> grid_last_;  // per pair: the last grid index (2 * half span)
  // Patches of neighbouring directions, each a union of groups of fewer neighbours: group q's
  // members (direction indices) at members_[group_offsets_[q] .. group_offsets_[q + 1]), patch
  // g's groups at [patch_offsets_[g], patch_offsets_[g + 1]). Per patch (group) and pair: the
  // two range_maxima_ entries whose larger is the range maximum over the lags its directions'
  // interpolations read.
  std::vector<std::int32_t> patch_offsets_;
  std::vector<std::int32_t> group_offsets_;
  std::vector<std::int32_t> members_;
  std::vector<std::int32_t> patch_low_;  // patches x pairs
  std::vector<std::int32_t> patch_high_;
  std::vector<std::int32_t> group_low_;  // groups x pairs
  std::vector<std::int32_t> group_high_;
  // Sparse table of range maxima of the residual: level l holds max over [m, m + 2^l).
  int range_levels_ = 0;
  mutable std::vector<double> range_maxima_;  // pairs x levels x grid_stride_
  mutable std::vector<double> patch_bounds_;  // patches
  mutable bool range_maxima_stale_ = true;
};

}  // namespace dronetrack::doa
