#pragma once
// Least-squares direction of arrival from pairwise TDOAs (SPEC 4.2, seed 002 eqs. 3-11).
// Far field: tau_ij = -dp_ij^T u with dp_ij = (p_i - p_j) / c. Weighted normal equations
// A = sum w dp dp^T, b = sum w tau dp, v = -A^-1 b, u = v / |v|, with w = 1 / var(tau).
// The geometry's rank decides what can be known: 3 -> full direction; 2 (planar) -> the
// direction and its mirror through the array plane (reported: the upper one); 1 (two mics or a
// line) -> only the angle to the axis, a cone (reported: the horizontal one on the cone).
// Output in the site frame, with the covariance of (azimuth, elevation) propagated from the
// TDOA variances and inflated by the fit's chi^2 per degree of freedom when that exceeds 1.
// Everything is solved in the array frame; the rotation to the site frame (and the choices that
// need "up": the cone's display point, the upper mirror image) happen in one place,
// LsDoaSolver::to_site(), so a moving array passes its per-frame attitude to solve().
// What a rank-deficient array measured is said as such: the cone's axis, angle and variance, or
// the mirror plane's normal (DoaSolution::ambiguity_axis_site; docs/doa.md "Cones and mirrors").
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
  // cone: the mic axis (unit, from mic 0 towards mic 1), so cos(cone_angle_rad) =
  // ambiguity_axis_site . (direction to the source); mirror_up_down: the array plane's unit
  // normal on the side of direction_site (the mirror image is direction_site - 2 (direction_site .
  // axis) axis); none: unused.
  Eigen::Vector3d ambiguity_axis_site = Eigen::Vector3d::UnitZ();
  double cone_angle_rad = 0.0;            // cone only, in [0, pi]
  double cone_angle_variance_rad2 = 0.0;  // cone only: see cone_angle_variance_rad2()
  double norm = 0.0;                      // |A^-1 b|, 1 for a consistent far-field plane wave
  double chi2_per_dof = 0.0;              // weighted residual at the normalised direction
  double quality = 0.0;                   // 0..1
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

  // Rank 1: the pair with the longest baseline (the finest cone angle), and the cosine of the
  // angle between the mic axis and the direction to a source that a TDOA of that pair means
  // (outside [-1, 1] for a TDOA beyond the physical lag).
  int cone_pair() const { return cone_pair_; }
  double cone_cosine_for_tdoa(int pair, double tdoa_s) const;

  // Solves; when the fit fails its gates and at least 5 pairs are usable, retries once without
  // the pair with the largest normalised residual. Site frame by the geometry's fixed attitude,
  // or by `array_to_site` (a moving array's attitude at the frame's time).
  DoaSolution solve(std::span<const PairTdoa> tdoas) const;
  DoaSolution solve(std::span<const PairTdoa> tdoas, const Eigen::Matrix3d& array_to_site) const;

 private:
  // A solution in the array frame: what the TDOAs say, before any choice that needs "up".
  struct ArrayFit {
    DoaSolution solution;  // its frame-free figures (accepted, norm, chi2, quality, pairs)
    // rank 3: the direction; rank 2: the image on the +normal side (subspace_ column 2).
    Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // of `direction`, inflated
    double cone_cosine = 0.0;     // rank 1: measured cos of the angle to the axis
    double cone_angle_rad = 0.0;  // rank 1
    double cone_angle_variance_rad2 = 0.0;
  };
  ArrayFit solve_once(std::span<const PairTdoa> tdoas, int skip_pair) const;
  // The one place the array frame turns into the site frame.
  DoaSolution to_site(const ArrayFit& fit, const Eigen::Matrix3d& array_to_site) const;
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
  // Columns: principal axes of the geometry, strongest first. Rank 1: column 0 points from mic 0
  // towards mic 1 (the published cone axis).
  Eigen::Matrix3d subspace_;
  int cone_pair_ = 0;
};

// How many dimensions of direction a set of mic positions resolves: 3 (a solid array), 2 (planar:
// up/down mirror), 1 (two mics or collinear: a cone), 0 (fewer than two distinct mics).
int direction_rank(const std::vector<Eigen::Vector3d>& mics_m);

// Variance (rad^2) of the cone angle theta^ = acos(clamp(c^, -1, 1)) reported for a measured
// cosine c^ = cos(theta) + e, e ~ N(0, cosine_variance): the mean squared distance of theta from
// theta^ under the posterior of cos(theta) given c^ (directions uniform on the sphere), by
// quadrature. Away from the axis it is the linearised cosine_variance / sin^2(theta); on the
// axis (c^ = +-1) the linearisation fails (theta ~ sqrt(2 |e|)) and it is
// 2 sqrt(2 / pi) sqrt(cosine_variance) (docs/doa.md "Cones and mirrors").
double cone_angle_variance_rad2(double measured_cosine, double cosine_variance);

// The unit direction -> (azimuth, elevation) Jacobian applied to a 3x3 direction covariance.
Eigen::Matrix2d azel_covariance_from_direction(const Eigen::Vector3d& unit_direction,
                                               const Eigen::Matrix3d& direction_covariance);

}  // namespace dronetrack::doa
