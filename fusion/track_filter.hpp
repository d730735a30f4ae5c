#pragma once
// One track's state estimator behind one interface (STYLE 11), chosen by FusionParams::filter:
//   ukf          scaled unscented KF (alpha, beta, kappa), default
//   ukf_seed002  the seed's UKF, n + kappa = 3 (negative centre weight), for comparison
//   ekf          extended KF, numerical Jacobian of the same h(x)
//   particle     bootstrap particle filter, robust likelihood (seeds 001/004)
// The constant-jerk model is linear, so the Gaussian filters predict exactly with F and Q; they
// differ in how they push the covariance through the nonlinear DOA model (and through the
// nonlinear coordinated-turn model, an IMM mode: UKF sigma points, EKF numerical Jacobian). The
// update is split in two so the tracker can gate and assign on the innovation before committing it.
// Nothing allocates per measurement (fixed-size Eigen; particles are allocated once, at
// construction).
#include <cstdint>
#include <memory>
#include <vector>

#include "fusion/fusion_params.hpp"
#include "fusion/measurement_model.hpp"
#include "fusion/motion_model.hpp"
#include "fusion/state.hpp"

namespace dronetrack::fusion {

enum class FilterStatus : std::uint8_t {
  ok = 0,
  repaired,  // a covariance was not positive definite and was repaired (eigenvalue clamp)
  failed,    // non-finite or unrepairable; the filter kept its previous state
};

struct Innovation {
  Measurement predicted = Measurement::Zero();                           // z_hat
  MeasurementCovariance covariance = MeasurementCovariance::Identity();  // S = ... + R
  CrossCovariance cross = CrossCovariance::Zero();                       // P_xz
  MeasurementCovariance noise = MeasurementCovariance::Identity();       // R
  const DoaMeasurementModel* model = nullptr;
  // Squared Mahalanobis distance of a measurement z under this innovation.
  double mahalanobis2(const Measurement& z) const;
};

// Which motion model a single Gaussian filter predicts with.
enum class MotionKind : std::uint8_t { constant_jerk, coordinated_turn };

struct FilterSettings {
  ConstantJerkModel motion;
  MotionKind motion_kind = MotionKind::constant_jerk;
  CoordinatedTurnModel turn;  // motion_kind == coordinated_turn (Gaussian filters only)
  double ukf_alpha = 1.0;
  double ukf_beta = 2.0;
  double ukf_kappa = 0.0;
  int particle_count = 1000;
  std::uint64_t random_seed = 1;
  // The particle filter's DOA likelihood: Gaussian plus a uniform floor (0), or the multivariate
  // Student-t of doa_likelihood.hpp with this many degrees of freedom (> 0), the same law the
  // Gaussian filters' reweighted update follows.
  double student_t_dof = 0.0;
  // Interacting multiple model (IMM) over jerk levels: with two or more levels, the Gaussian
  // filters (ukf, ukf_seed002, ekf) run one constant-jerk model per level and mix them
  // (Blom & Bar-Shalom); `motion` is then unused. A mode is kept for imm_sojourn_s on average.
  std::vector<double> imm_jerk_std_mps3;
  double imm_sojourn_s = 2.0;
  // Coordinated-turn modes added to the IMM, one per turn-rate noise level (std of omega',
  // rad/s^2), each with the isotropic jerk std imm_turn_jerk_std_mps3. Empty: no turn mode.
  // The IMM runs when jerk levels + turn levels >= 2.
  std::vector<double> imm_turn_rate_std_radps2;
  double imm_turn_jerk_std_mps3 = 0.2;
};

class TrackFilter {
 public:
  virtual ~TrackFilter() = default;
  virtual void initialise(const StateVector& mean, const StateCovariance& covariance) = 0;
  virtual void predict(double dt_s) = 0;
  // Predicted measurement and its covariance for this array, including the noise R.
  virtual FilterStatus innovation(const DoaMeasurementModel& model,
                                  const MeasurementCovariance& noise, Innovation& out) = 0;
  // Commits z against the innovation computed last (same model, no predict in between).
  virtual FilterStatus update(const Innovation& innovation, const Measurement& z) = 0;
  virtual const StateVector& mean() const = 0;
  virtual const StateCovariance& covariance() const = 0;
  // Probability of each motion mode (one entry for a single-model filter).
  virtual int mode_count() const { return 1; }
  virtual double mode_probability(int /*mode*/) const { return 1.0; }
};

std::unique_ptr<TrackFilter> make_track_filter(FilterKind kind, const FilterSettings& settings);

// Cholesky factor of a covariance that survives round-off: on failure the matrix is symmetrised
// and its eigenvalues clamped to a small positive floor (in place). Returns failed if even that
// does not give a finite factor.
FilterStatus robust_cholesky(StateCovariance& covariance, StateCovariance& lower);
// True when symmetric positive definite and finite.
bool is_positive_definite(const StateCovariance& covariance);

}  // namespace dronetrack::fusion
