#pragma once
// One track's state estimator behind one interface (STYLE 11), chosen by FusionParams::filter:
//   ukf          scaled unscented KF (alpha, beta, kappa), default
//   ukf_seed002  the seed's UKF, n + kappa = 3 (negative centre weight), for comparison
//   ekf          extended KF, numerical Jacobian of the same h(x)
//   particle     bootstrap particle filter, robust likelihood (seeds 001/004)
// and the one-array localisers (issue 15; fusion_params.hpp): gaussian_sum
// (gaussian_sum_filter.hpp), ekf_range_init (the EKF started by seed 000's range initialisation),
// particle_multipeak (the particle filter started over the region, weighed by the GCC's top peaks).
// The constant-jerk model is linear, so the Gaussian filters predict exactly with F and Q; they
// differ in how they push the covariance through the nonlinear DOA model (and through the
// nonlinear coordinated-turn model, an IMM mode: UKF sigma points, EKF numerical Jacobian). The
// update is split in two so the tracker can gate and assign on the innovation before committing it.
// Nothing allocates per measurement (fixed-size Eigen; particles are allocated once, at
// construction).
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "doa/doa_measurement.hpp"
#include "fusion/bearing_prior.hpp"
#include "fusion/doa_likelihood.hpp"
#include "fusion/fusion_params.hpp"
#include "fusion/innovation.hpp"
#include "fusion/measurement_model.hpp"
#include "fusion/motion_model.hpp"
#include "fusion/state.hpp"

namespace dronetrack::fusion {

enum class FilterStatus : std::uint8_t {
  ok = 0,
  repaired,  // a covariance was not positive definite and was repaired (eigenvalue clamp)
  failed,    // non-finite or unrepairable; the filter kept its previous state
};

// The other readings of one DOA (seed 004's multi-peak GCC, SPEC 4.3): the GCC's strongest peaks as
// measurements of the model's kind (cone angles), strongest first, with their GCC values as
// weights. count 0: none beyond z.
struct MeasurementPeaks {
  int count = 0;
  std::array<Measurement, doa::kMaxConePeaks> value{};
  std::array<double, doa::kMaxConePeaks> weight{};
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
  // The DOA likelihood every filter weighs a DOA by in its own update (doa_likelihood.hpp); the
  // tracker gates and assigns by the same.
  DoaLikelihood likelihood;
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
  // One-array localisers (issue 15): the hypotheses, priors and region a track started from one
  // DOA uses, and the source plane. The plane binds every filter whose settings carry it (the
  // tracker gives it to one-array tracks only).
  OneArrayParams one_array;
  // Gaussian filters: initialise_from_bearing places one Gaussian at r_init (seed 000).
  bool range_initialisation = false;
  // Particle filter: weigh by the GCC's top peaks (seed 004) when the DOA carries them.
  bool multipeak_likelihood = false;
  // Particle filter: after resampling, jitter each particle by half the last DOA's likelihood
  // width at its range (a cloud spread over a region), not by the cloud's covariance.
  bool local_jitter = false;
};

class TrackFilter {
 public:
  virtual ~TrackFilter() = default;
  virtual void initialise(const StateVector& mean, const StateCovariance& covariance) = 0;
  virtual void predict(double dt_s) = 0;
  // Predicted measurement and its covariance for this array, including the noise R.
  virtual FilterStatus innovation(const DoaMeasurementModel& model,
                                  const MeasurementCovariance& noise, Innovation& out) = 0;
  // Commits z against the innovation computed last (same model, no predict in between), weighed
  // by the settings' DOA likelihood: each filter applies it itself (a Gaussian filter by its
  // inlier probability or reweighted R, the particle filter as each particle's density, the IMM
  // in each mode and in the modes' weights).
  virtual FilterStatus update(const Innovation& innovation, const Measurement& z) = 0;
  virtual const StateVector& mean() const = 0;
  virtual const StateCovariance& covariance() const = 0;
  // Starts from what one DOA alone says (issue 15): no range, maybe a mirror side. False when this
  // filter cannot hold such a prior (the tracker then waits for a second array).
  virtual bool initialise_from_bearing(const BearingLocus& /*locus*/) { return false; }
  // The hypotheses about the source it still carries: 1 for a single Gaussian or a particle cloud,
  // more for a Gaussian sum whose range or mirror side is not yet resolved.
  virtual int hypothesis_count() const { return 1; }
  // update() for a DOA that carries its GCC's other peaks (seed 004): filters whose likelihood
  // uses them override it; the others take z alone.
  virtual FilterStatus update_with_peaks(const Innovation& innovation, const Measurement& z,
                                         const MeasurementPeaks& /*peaks*/) {
    return update(innovation, z);
  }
  // Widens the state's covariance by `extra` (a manoeuvre the motion model did not expect: the
  // tracker's manoeuvre onset test), in every mode of an IMM. False when this filter cannot.
  virtual bool add_process_noise(const StateCovariance& /*extra*/) { return false; }
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
// S must be a finite, positive-definite 2x2 for gating, the gain and the weights.
bool valid_innovation_covariance(const MeasurementCovariance& s);
// The moment-matched innovation of a mixture of filters (the IMM's modes, the Gaussian sum's
// hypotheses): component j, where ok[j], weighs weights[j] / weight_sum; angles are wrapped
// offsets from the reference component's prediction, so a mixture across +-180 deg keeps its
// mean. `mixture_mean` is the mixture's state mean. False when the moment-matched S is no
// covariance (`out` is then left as it was).
bool mixture_innovation(const DoaMeasurementModel& model, const MeasurementCovariance& noise,
                        std::span<const std::unique_ptr<TrackFilter>> components,
                        std::span<const Innovation> innovations, std::span<const char> ok,
                        std::span<const double> weights, double weight_sum, std::size_t reference,
                        const StateVector& mixture_mean, Innovation& out);

}  // namespace dronetrack::fusion
