#pragma once
// Least-squares direction of arrival from pairwise TDOAs (SPEC 4.2, seed 002 eqs. 3-11).
// Far field: tau_ij = -dp_ij^T u with dp_ij = (p_i - p_j) / c. Weighted normal equations
// A = sum w dp dp^T, b = sum w tau dp, v = -A^-1 b, u = v / |v|, with w = 1 / var(tau).
// The geometry's rank decides what can be known: 3 -> full direction; 2 (planar) -> the
// direction and its mirror through the array plane (reported: the upper one); 1 (two mics or a
// line) -> only the angle to the axis, a cone (reported: the horizontal one on the cone).
// Output in the site frame, with the covariance of (azimuth, elevation) propagated from the
// TDOA variances and inflated by the fit's chi^2 per degree of freedom when that exceeds 1.
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"

namespace dronetrack::doa {

inline constexpr int kMaxMics = 8;  // kMaxPairs = 8 * 7 / 2

struct PairTdoa {
  double tdoa_s = 0.0;
  double variance_s2 = 0.0;  // <= 0 or non-finite: pair not used
  double peak_value = 0.0;   // GCC quality, for the DOA's quality figure
  double coherence = 0.0;    // coherent share of the in-band power at this lag (detection)
};

struct LsDoaSettings {
  double speed_of_sound_mps = 343.0;
  double max_norm_error = 0.25;    // reject when ||A^-1 b| - 1| exceeds this (rank 3)
  double max_chi2_per_dof = 30.0;  // reject when the fit residual exceeds this
  double timing_floor_s = 0.5e-6;  // added in quadrature to every pair's TDOA std
  // Near field: a source at range r bends the wavefront across the array by ~|p|^2 / (2 r c),
  // tens of microseconds at 20 m for a 0.5 m arm. A tetrahedron (not centrally symmetric) turns
  // that curvature into a direction bias of ~0.2-0.3 deg, so (for 3-D arrays) the plane-wave
  // solution is refined with a spherical wavefront, curvature kappa = 1/r a nuisance parameter
  // with a zero-mean prior of this standard deviation (1/m). 0 disables.
  double near_field_kappa_std_per_m = 0.05;
};

struct DoaSolution {
  bool accepted = false;
  Eigen::Vector3d direction_site = Eigen::Vector3d::UnitX();
  Eigen::Matrix2d azel_covariance_rad2 = Eigen::Matrix2d::Identity();
  DoaAmbiguity ambiguity = DoaAmbiguity::none;
  double norm = 0.0;          // |A^-1 b|, 1 for a consistent far-field plane wave
  double chi2_per_dof = 0.0;  // weighted residual at the normalised direction
  double quality = 0.0;       // 0..1
  int pairs_used = 0;
  int dropped_pair = -1;  // pair left out as an outlier, -1 if none
};

class LsDoaSolver {
 public:
  // Pairs are all i<j in lexicographic order (the order of DoaMeasurement::tdoa_s).
  LsDoaSolver(const ArrayGeometry& geometry, const LsDoaSettings& settings);

  int pair_count() const { return static_cast<int>(pair_vectors_.size()); }
  int rank() const { return rank_; }
  DoaAmbiguity ambiguity() const;
  // Maximum |tau| of each pair: |p_i - p_j| / c.
  double max_lag_s(int pair) const { return max_lags_s_[static_cast<std::size_t>(pair)]; }
  int pair_mic_i(int pair) const { return pair_mics_[static_cast<std::size_t>(pair)].first; }
  int pair_mic_j(int pair) const { return pair_mics_[static_cast<std::size_t>(pair)].second; }
  // TDOA of a pair for a far-field source in `direction_array` (array frame, unit).
  double tdoa_for_direction(int pair, const Eigen::Vector3d& direction_array) const;
  const Eigen::Matrix3d& array_to_site() const { return array_to_site_; }

  // Solves; when the fit fails its gates and at least 5 pairs are usable, retries once without
  // the pair with the largest normalised residual.
  DoaSolution solve(std::span<const PairTdoa> tdoas) const;

 private:
  DoaSolution solve_once(std::span<const PairTdoa> tdoas, int skip_pair) const;
  // Gauss-Newton on (direction, kappa) from the plane-wave direction; false if it diverged.
  bool refine_near_field(std::span<const PairTdoa> tdoas, int skip_pair,
                         Eigen::Vector3d& direction_array, Eigen::Matrix3d& covariance,
                         double& chi2) const;
  // Arrival time at a mic (relative to the mic centroid) of a spherical wavefront from
  // direction u with curvature kappa, and its derivatives by u.m and by kappa.
  struct Arrival {
    double time_s = 0.0;
    double d_along = 0.0;  // s per m of u.m
    double d_kappa = 0.0;  // s per (1/m)
  };
  Arrival arrival(const Eigen::Vector3d& direction_array, double kappa, int mic) const;
  double pair_variance(const PairTdoa& tdoa) const;

  LsDoaSettings settings_;
  Eigen::Matrix3d array_to_site_;
  std::vector<Eigen::Vector3d> pair_vectors_;  // (p_i - p_j) / c, array frame, s/unit
  std::vector<std::pair<int, int>> pair_mics_;
  std::vector<double> max_lags_s_;
  std::vector<Eigen::Vector3d> mics_centred_m_;  // array frame, relative to the mic centroid
  double position_variance_s2_ = 0.0;            // TDOA variance from mic position uncertainty
  int rank_ = 0;
  Eigen::Matrix3d subspace_;  // columns: principal axes of the geometry, strongest first
};

// The unit direction -> (azimuth, elevation) Jacobian applied to a 3x3 direction covariance.
Eigen::Matrix2d azel_covariance_from_direction(const Eigen::Vector3d& unit_direction,
                                               const Eigen::Matrix3d& direction_covariance);

}  // namespace dronetrack::doa
