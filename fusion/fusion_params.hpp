#pragma once
// Fusion parameters. Parsed and validated in config/ (parse_fusion_params.cpp).
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "fusion/array_mirror_check.hpp"
#include "fusion/track_classifier.hpp"

namespace dronetrack::fusion {

// ukf, ukf_seed002, ekf, particle: track_filter.hpp. The one-array localisers (issue 15), which
// can also start from a single DOA (TrackFilter::initialise_from_bearing):
//   gaussian_sum        seed 003: EKF hypotheses at spaced ranges along the bearing's locus
//   ekf_range_init      seed 000: one EKF at r_init along the bearing, covariance from sigma_r and
//                       sigma_theta (eqs. 15-16)
//   particle_multipeak  seed 004: particles spread over the region with no initial guess, weighed
//                       by the GCC's top peaks (a mixture likelihood)
enum class FilterKind {
  ukf,
  ukf_seed002,
  ekf,
  particle,
  gaussian_sum,
  ekf_range_init,
  particle_multipeak
};

// How a track starts from one array's DOA alone, and how the one-array localisers run (issue 15;
// seeds 000, 003, 004). Keys under fusion.single_array (docs/fusion.md).
struct OneArrayParams {
  // Seed 003: Gaussians along the bearing, the first at hypothesis_spacing_m, each next one
  // max(hypothesis_spacing_m, (hypothesis_range_ratio - 1) r) further out (evenly spaced near the
  // array, geometrically beyond: a range-parameterised sum, Peach 1995, whose every Gaussian has a
  // range std of at most (ratio - 1) / 2 of its range, so each EKF is linearised within its own
  // spread), hypotheses_per_side of them at most on each branch (a ray, or each mirror side), none
  // beyond max_range_m (nor the fusion's init_max_range_m). Each has a range std of half the gap
  // to the next and a weight in proportion to that gap, so the sum is near flat in range (seed
  // 003 Fig. 3's uniform range prior) out to the last. A ratio of 1 is seed 003's even spacing.
  double hypothesis_spacing_m = 15.0;
  double hypothesis_range_ratio = 1.3;
  int hypotheses_per_side = 24;
  // The one-array localisers' region: no hypothesis beyond it; seed 004's particles on a disc of
  // this radius on the source plane (a ball without one). The engine also bounds it by
  // init_max_range_m (no track is placed farther from every array).
  double max_range_m = 2000.0;
  // Seed 003 eq. 10: a hypothesis whose weight falls below gamma / N is pruned.
  double prune_gamma = 0.1;
  // Two hypotheses merge into their moment-matched Gaussian when that loses little (Runnalls'
  // bound on the Kullback-Leibler discrimination, position block): ln det P_merged - the weighted
  // mean of ln det P_i below ln(1 + merge_d2 / 4), which for equal weights and covariances is a
  // squared Mahalanobis distance below merge_d2. Two wide hypotheses that overlap along the
  // bearing (the range still open) do not merge: their merged Gaussian is wider than either.
  double merge_d2 = 1.0;
  // Eq. 9's weights on each hypothesis's own innovation covariance S_i (seed 003 as printed)
  // rather than the mixture's common S (gaussian_sum_filter.cpp: from a static array ln det S_i
  // ranks the ranges by the motion prior, not by the data). Key single_array.own_spread_weights.
  bool own_spread_weights = false;
  // The fastest a source moves (the engine sets it from init_max_speed_mps; not a key of its own).
  // A hypothesis whose velocity the bearings have placed above it (its mixture weight times the
  // probability that its speed is below it, along its velocity's direction) holds little of the
  // reported mixture: a static array's bearings fix the angular rates, and the range only up to
  // the speed those rates need.
  double max_speed_mps = 25.0;
  // Seed 000 eqs. 15-16: r_init, sigma_r, sigma_theta (paper: 50 m, 25 m, 10 deg).
  double range_init_m = 50.0;
  double range_init_std_m = 25.0;
  double bearing_init_std_deg = 10.0;
  // The motion the one-array localisers assume: a constant-jerk model at this jerk std (static and
  // slow sources), and the prior's velocity and acceleration std.
  double jerk_std_mps3 = 0.5;
  double velocity_std_mps = 10.0;
  double acceleration_std_mps2 = 3.0;
  int particle_count = 2000;  // seed 004's simulation
  // The known plane the sources lie on (site z, m), absent by default. A two-mic array's cone
  // alone cannot fix height (the papers' problem is 2-D): with a plane, the cone cuts it in two
  // branches, and the one-array localisers hold z = source_plane_z_m (std source_plane_std_m),
  // v_z = a_z = 0 by a pseudo-measurement after every step. Without one, a cone cannot start a
  // track.
  std::optional<double> source_plane_z_m;
  double source_plane_std_m = 0.1;
};

// The DOA likelihood of every filter's update, the gates and the assignment (doa_likelihood.hpp).
enum class DoaLikelihoodKind { gaussian, student_t, outlier_mixture };
// How a new track's first position is found (SPEC 4.4).
enum class TriangulationMethod { least_squares_3d, seed_xy_projection };

struct FusionParams {
  FilterKind filter = FilterKind::ukf;
  // sqrt(q) of the constant-jerk model (SPEC 4.5) when imm_jerk_std_mps3 has fewer than two
  // levels, and of the particle filter.
  double jerk_noise_std_mps3 = 5.0;
  double output_rate_hz = 10.0;     // track reports per second
  double reorder_window_s = 0.3;    // DOAs are fed oldest first after this delay
  double gate_probability = 0.999;  // gate on the DOA innovation (chi-square, or Student-t's)
  // outlier_mixture: a reflection, a gust or one frame of another source costs a track little
  // (docs/fusion.md "Impulsive DOA errors"; the default since session 12, issue 17).
  DoaLikelihoodKind likelihood = DoaLikelihoodKind::outlier_mixture;
  double student_t_dof = 10.0;  // likelihood = student_t (10: tested, docs/fusion.md)
  // likelihood = outlier_mixture: prior probability that a gated DOA is not the track's but
  // uniform over the gate (docs/fusion.md "Impulsive DOA errors").
  double outlier_probability = 0.1;
  // likelihood = outlier_mixture: e estimated per array from its DOAs gated to confirmed tracks
  // (outlier_share.hpp), the maximum of its posterior over the array's last outlier_window_doas
  // such DOAs with a Beta prior of mean outlier_probability worth outlier_prior_doas DOAs
  // (docs/fusion.md "Estimating e"). Off: e = outlier_probability everywhere.
  bool adaptive_outlier_probability = false;
  int outlier_window_doas = 500;
  double outlier_prior_doas = 10.0;
  int confirm_hits = 5;          // M of N: M
  int confirm_window = 8;        //         N
  double coast_timeout_s = 3.0;  // a track unheard this long is deleted

  // Scaled unscented transform (filter = ukf). alpha = 1, kappa = 0 keeps every weight >= 0.
  double ukf_alpha = 1.0;
  double ukf_beta = 2.0;
  double ukf_kappa = 0.0;
  int particle_count = 1000;  // filter = particle
  // Point h(x) at the emission time (sound takes r / c to arrive). Off only for comparison.
  bool model_propagation_delay = true;
  TriangulationMethod triangulation = TriangulationMethod::least_squares_3d;
  // Added in quadrature to each DOA's own angular std: model error (array pose, wind, refraction,
  // ground echo, a masked second drone). Measured on all bundled scenes' DOAs against truth: the
  // mean normalised error z^2 (2 when honest) is 2.5 at 0.15 deg, 1.8 at 0.2 deg, 4-12 without.
  double doa_noise_floor_deg = 0.2;
  double coast_after_s = 0.5;        // a confirmed track unheard this long reports "coasting"
  double tentative_timeout_s = 1.5;  // a tentative track unheard this long is deleted
  // Initiation: DOAs of different arrays this close in time are paired and triangulated.
  double init_pair_window_s = 0.3;
  double init_max_range_m = 2000.0;  // candidate points farther from every array are rejected
  double init_max_speed_mps = 25.0;  // bounds the motion between paired DOAs (widens their gate)
  double init_velocity_std_mps = 10.0;
  double init_acceleration_std_mps2 = 3.0;
  int max_tracks = 32;
  // Ghost rejection by continuity: a tentative track is confirmed only once this many distinct
  // arrays have updated it (clamped to the number of arrays). A crossing of two drones' rays is
  // consistent with the two arrays that made it, rarely with a third.
  // Two arrays that each updated it confirm_hits times also suffice (continuity: a ghost does not
  // keep agreeing with both while the drones move), for a drone the other arrays cannot hear.
  int confirm_min_arrays = 3;
  // A track whose position std (largest axis) grows beyond this is lost, not tracked: deleted.
  double max_position_std_m = 50.0;
  // Interacting multiple model over jerk levels (m/s^3): cruising in gusts (acceleration drifting
  // ~0.2 m/s^2 per second), gentle manoeuvres, and a turn entry (6 m/s^2 of centripetal
  // acceleration within 0.2 s). Two or more levels: the Gaussian filters mix one constant-jerk
  // model per level and jerk_noise_std_mps3 is unused (the particle filter keeps it). One level: a
  // single model at that level.
  std::vector<double> imm_jerk_std_mps3{0.2, 3.0, 30.0};
  // Mean time a motion mode lasts (Markov switching). It also sets how much weight the modes not
  // in play keep: ~1/sojourn per second flows into each, and at 300 m those modes' estimates
  // wander by tens of metres (docs/fusion.md: far pass 3.25 m at 20 s, 2.97 m at 60 s).
  double imm_sojourn_s = 60.0;
  // Coordinated-turn IMM modes (CoordinatedTurnModel on the same 9 states: v_h and a_h rotate at
  // omega = (v x a)_z / |v_h|^2, the position follows the arc) when imm_turn_mode is on, one per
  // level of turn-rate noise: std of omega' in rad/s^2 (a jerk of that times the speed along the
  // horizontal normal: 2.5 / 15 / 100 m/s^3 at 5 m/s: holding a turn, easing in, a corner's entry).
  // Each also has an isotropic jerk noise of imm_turn_jerk_std_mps3. Measured on the bundled
  // scenes (docs/fusion.md): seed002 RMSE 0.644 -> 0.569 m, its 40 dB twin 0.456 -> 0.342 m.
  bool imm_turn_mode = true;
  std::vector<double> imm_turn_rate_std_radps2{0.5, 3.0, 20.0};
  double imm_turn_jerk_std_mps3 = 0.2;
  // DOA errors are correlated over this span (the nodes smooth TDOAs over a sliding window, and
  // their frames overlap): the DOA errors' autocorrelation on the bundled scenes falls to 0.5 after
  // 0.2 s and to 0 after 0.4 s, an integrated correlation time of ~0.3 s. DOAs of one array
  // within it carry about one DOA's information, so a DOA taken dt after the track's previous one
  // from that array has its covariance scaled by max(1, doa_error_correlation_s / dt).
  // 0: every DOA independent (overconfident at 20 DOAs/s).
  double doa_error_correlation_s = 0.3;
  // Ground height in the site frame (z up; the bundled sites and the simulator put the ground at
  // z = 0 with the arrays 1.5-2 m above it). A triangulated point more than 3 sigma below it is a
  // ground-reflection image (a node reports the echo as a second source), never a drone: no track
  // starts there.
  double ground_altitude_m = 0.0;
  // Issue 15: a track may start from ONE array's DOAs (no second array within init_pair_window_s),
  // with single_array_filter; off by default (the default scenes are started by triangulation).
  bool single_array_start = false;
  FilterKind single_array_filter = FilterKind::gaussian_sum;
  OneArrayParams single_array;
  // Drone or not (issue 14): docs/classification.md.
  ClassifierSettings classifier;
  // Two channels swapped on an array whose swap is a mirror (issue 16), judged against tracks
  // fixed by the other arrays: fusion/array_mirror_check.hpp, docs/calibration.md.
  MirrorCheckSettings mirror_check;
};

// A zone alerts when a track enters or leaves it: a polygon in the x-y plane (site frame)
// with an altitude band.
struct Zone {
  std::string name;
  std::vector<Eigen::Vector2d> polygon_m;
  double altitude_min_m = -1e9;
  double altitude_max_m = 1e9;
};

}  // namespace dronetrack::fusion
