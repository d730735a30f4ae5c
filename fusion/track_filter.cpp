#include "fusion/track_filter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "fusion/gaussian_sum_filter.hpp"

namespace dronetrack::fusion {
namespace {

constexpr double kEigenFloorRelative = 1e-12;
constexpr double kEigenFloorAbsolute = 1e-12;

void symmetrise(StateCovariance& covariance) {
  covariance = 0.5 * (covariance + covariance.transpose()).eval();
}

// Shared by the Gaussian filters: exact linear prediction, the Kalman update from (S, P_xz).
class GaussianFilter : public TrackFilter {
 public:
  explicit GaussianFilter(const FilterSettings& settings) : settings_(settings) {}
  void initialise(const StateVector& mean, const StateCovariance& covariance) override {
    mean_ = mean;
    covariance_ = covariance;
    symmetrise(covariance_);
    hold_to_plane();
  }
  // Seed 000 eqs. 15-16: one Gaussian at r_init along the bearing (the branch the node's display
  // direction points to), covariance J diag(sigma_r^2, sigma_theta^2) J^T.
  bool initialise_from_bearing(const BearingLocus& locus) override {
    if (!settings_.range_initialisation) return false;
    const OneArrayParams& p = settings_.one_array;
    const auto offset = locus.offset_at(locus.preferred_branch(p.range_init_m), p.range_init_m);
    if (!offset) return false;
    StateVector mean;
    StateCovariance covariance;
    state_at(locus.model.centre_m + *offset,
             range_bearing_covariance(*offset, p.range_init_std_m,
                                      p.bearing_init_std_deg * std::numbers::pi / 180.0),
             p, mean, covariance);
    initialise(mean, covariance);
    return true;
  }
  void predict(double dt_s) override {
    if (dt_s == 0.0) return;
    if (settings_.motion_kind == MotionKind::constant_jerk) {
      settings_.motion.predict(mean_, covariance_, dt_s);
      hold_to_plane();
      return;
    }
    predict_nonlinear(dt_s);
    // A linearised or sampled covariance over a long gap can lose definiteness to round-off:
    // repair it here (eigenvalue clamp) so every mode hands the mixing a valid covariance.
    StateCovariance lower;
    robust_cholesky(covariance_, lower);
    hold_to_plane();
  }
  // The DOA likelihood weighs z first (doa_likelihood.hpp): the Student-t by widening R, the
  // outlier mixture by the inlier probability beta. With beta the result is the mixture
  // posterior's mean and covariance: x + beta K nu, and P - beta K S K' for the inlier branch plus
  // beta (1 - beta) (K nu)(K nu)' for the spread between the two branches. R / beta instead would
  // barely hold back a DOA when the prediction, not R, dominates S.
  FilterStatus update(const Innovation& innovation, const Measurement& z) override {
    if (!valid_innovation_covariance(innovation.covariance) || !z.allFinite()) {
      return FilterStatus::failed;
    }
    Innovation weighed = innovation;
    const double inlier = settings_.likelihood.weigh(weighed, z);
    if (!valid_innovation_covariance(weighed.covariance)) return FilterStatus::failed;
    const CrossCovariance gain = weighed.cross * weighed.covariance.inverse();
    const StateVector correction = gain * weighed.residual(z);
    const StateVector mean = mean_ + inlier * correction;
    StateCovariance covariance =
        covariance_ - inlier * gain * weighed.covariance * gain.transpose();
    if (inlier < 1.0)
      covariance.noalias() += inlier * (1.0 - inlier) * correction * correction.transpose();
    symmetrise(covariance);
    if (!mean.allFinite() || !covariance.allFinite()) return FilterStatus::failed;
    StateCovariance lower;
    const FilterStatus status = robust_cholesky(covariance, lower);
    if (status == FilterStatus::failed) return status;
    mean_ = mean;
    covariance_ = covariance;
    hold_to_plane();
    return status;
  }
  const StateVector& mean() const override { return mean_; }
  const StateCovariance& covariance() const override { return covariance_; }
  bool add_process_noise(const StateCovariance& extra) override {
    covariance_ += extra;
    symmetrise(covariance_);
    return true;
  }

 protected:
  // The known source plane (issue 15), when the settings carry one: a pseudo-measurement.
  void hold_to_plane() {
    const OneArrayParams& p = settings_.one_array;
    if (p.source_plane_z_m)
      constrain_to_plane(mean_, covariance_, *p.source_plane_z_m, p.source_plane_std_m);
  }

  // Coordinated turn, linearised (EKF): F = numerical Jacobian at the mean.
  virtual void predict_nonlinear(double dt_s) {
    const StateCovariance f = settings_.turn.jacobian(mean_, dt_s);
    const StateCovariance q = settings_.turn.process_noise(mean_, dt_s);
    const StateVector mean = settings_.turn.propagate(mean_, dt_s);
    StateCovariance covariance = f * covariance_ * f.transpose() + q;
    symmetrise(covariance);
    if (!mean.allFinite() || !covariance.allFinite()) return;  // keep the previous state
    mean_ = mean;
    covariance_ = covariance;
  }

  FilterSettings settings_;
  StateVector mean_ = StateVector::Zero();
  StateCovariance covariance_ = StateCovariance::Identity();
};

// Scaled unscented transform (Julier/Wan-van der Merwe): lambda = alpha^2 (n + kappa) - n,
// Wm0 = lambda / (n + lambda), Wc0 = Wm0 + 1 - alpha^2 + beta, Wi = 1 / (2 (n + lambda)).
// The seed's variant (seed 002 eqs. 19-24) is alpha = 1, beta = 0, kappa = 3 - n.
class UnscentedFilter final : public GaussianFilter {
 public:
  UnscentedFilter(const FilterSettings& settings, double alpha, double beta, double kappa)
      : GaussianFilter(settings) {
    constexpr double n = kStateSize;
    const double lambda = alpha * alpha * (n + kappa) - n;
    spread_ = std::sqrt(n + lambda);
    weight_mean0_ = lambda / (n + lambda);
    weight_cov0_ = weight_mean0_ + 1.0 - alpha * alpha + beta;
    weight_i_ = 1.0 / (2.0 * (n + lambda));
  }

  FilterStatus innovation(const DoaMeasurementModel& model, const MeasurementCovariance& noise,
                          Innovation& out) override {
    StateCovariance lower;
    const FilterStatus factor_status = robust_cholesky(covariance_, lower);
    if (factor_status == FilterStatus::failed) return factor_status;
    constexpr int kPoints = 2 * kStateSize + 1;
    Eigen::Matrix<double, kStateSize, kPoints> points;
    Eigen::Matrix<double, kMeasurementSize, kPoints> predicted;
    points.col(0) = mean_;
    for (int i = 0; i < kStateSize; ++i) {
      points.col(1 + i) = mean_ + spread_ * lower.col(i);
      points.col(1 + kStateSize + i) = mean_ - spread_ * lower.col(i);
    }
    for (int i = 0; i < kPoints; ++i) predicted.col(i) = model.predict(points.col(i));
    // Mean of angles: average the wrapped offsets from the centre point, not the raw angles.
    Measurement offset = Measurement::Zero();
    for (int i = 1; i < kPoints; ++i) {
      offset += weight_i_ * model.residual(predicted.col(i), predicted.col(0));
    }
    const Measurement z_hat = model.residual(predicted.col(0) + offset, Measurement::Zero());
    MeasurementCovariance s = noise;
    CrossCovariance cross = CrossCovariance::Zero();
    for (int i = 0; i < kPoints; ++i) {
      const double weight = i == 0 ? weight_cov0_ : weight_i_;
      const Measurement dz = model.residual(predicted.col(i), z_hat);
      s += weight * dz * dz.transpose();
      cross += weight * (points.col(i) - mean_) * dz.transpose();
    }
    s = 0.5 * (s + s.transpose()).eval();
    if (!valid_innovation_covariance(s)) {
      // The seed's negative centre weight can make S indefinite: fall back on R alone plus the
      // non-negative part, which keeps the gate meaningful.
      const Eigen::SelfAdjointEigenSolver<MeasurementCovariance> eigen(s);
      if (eigen.info() != Eigen::Success) return FilterStatus::failed;
      const Eigen::Vector2d clamped = eigen.eigenvalues().cwiseMax(noise.diagonal().minCoeff());
      s = eigen.eigenvectors() * clamped.asDiagonal() * eigen.eigenvectors().transpose();
      if (!valid_innovation_covariance(s)) return FilterStatus::failed;
      out = {z_hat, s, cross, noise, &model, std::nullopt};
      return FilterStatus::repaired;
    }
    out = {z_hat, s, cross, noise, &model, std::nullopt};
    return factor_status;
  }

 protected:
  // Coordinated turn through the sigma points: f applied to each, weighted moments, + Q.
  void predict_nonlinear(double dt_s) override {
    StateCovariance lower;
    if (robust_cholesky(covariance_, lower) == FilterStatus::failed) return;
    constexpr int kPoints = 2 * kStateSize + 1;
    Eigen::Matrix<double, kStateSize, kPoints> points;
    points.col(0) = settings_.turn.propagate(mean_, dt_s);
    for (int i = 0; i < kStateSize; ++i) {
      points.col(1 + i) = settings_.turn.propagate(mean_ + spread_ * lower.col(i), dt_s);
      points.col(1 + kStateSize + i) =
          settings_.turn.propagate(mean_ - spread_ * lower.col(i), dt_s);
    }
    StateVector mean = weight_mean0_ * points.col(0);
    for (int i = 1; i < kPoints; ++i) mean += weight_i_ * points.col(i);
    StateCovariance covariance = settings_.turn.process_noise(mean_, dt_s);
    for (int i = 0; i < kPoints; ++i) {
      const StateVector d = points.col(i) - mean;
      covariance.noalias() += (i == 0 ? weight_cov0_ : weight_i_) * d * d.transpose();
    }
    symmetrise(covariance);
    if (!mean.allFinite() || !covariance.allFinite()) return;  // keep the previous state
    mean_ = mean;
    covariance_ = covariance;
  }

 private:
  double spread_ = 3.0;
  double weight_mean0_ = 0.0;
  double weight_cov0_ = 0.0;
  double weight_i_ = 0.0;
};

// EKF (seeds 000/004): H by central differences of the same h(x), so the propagation delay is
// linearised too.
class ExtendedFilter final : public GaussianFilter {
 public:
  using GaussianFilter::GaussianFilter;
  FilterStatus innovation(const DoaMeasurementModel& model, const MeasurementCovariance& noise,
                          Innovation& out) override {
    const Measurement z_hat = model.predict(mean_);
    const Eigen::Matrix<double, kMeasurementSize, kStateSize> jacobian =
        central_difference_jacobian<kMeasurementSize>(
            mean_, [&](const StateVector& state) { return model.predict(state); },
            [&](const Measurement& a, const Measurement& b) { return model.residual(a, b); });
    const CrossCovariance cross = covariance_ * jacobian.transpose();
    MeasurementCovariance s = jacobian * cross + noise;
    s = 0.5 * (s + s.transpose()).eval();
    if (!valid_innovation_covariance(s) || !z_hat.allFinite()) return FilterStatus::failed;
    out = {z_hat, s, cross, noise, &model, std::nullopt};
    return FilterStatus::ok;
  }
};

// Bootstrap particle filter with a robust likelihood: a Gaussian plus a small constant floor,
// so one wild DOA (reflection, other drone) cannot wipe out the particle cloud (seed 001).
// Resampling is systematic when the effective sample size drops under half, followed by a small
// Gaussian jitter from the cloud's own covariance (regularised PF) against sample impoverishment.
class ParticleFilter final : public TrackFilter {
 public:
  explicit ParticleFilter(const FilterSettings& settings)
      : settings_(settings),
        particles_(kStateSize, settings.particle_count),
        resampled_(kStateSize, settings.particle_count),
        weights_(settings.particle_count),
        predicted_(kMeasurementSize, settings.particle_count),
        random_(settings.random_seed) {}

  void initialise(const StateVector& mean, const StateCovariance& covariance) override {
    StateCovariance lower;
    StateCovariance repaired = covariance;
    robust_cholesky(repaired, lower);
    for (Eigen::Index i = 0; i < particles_.cols(); ++i) {
      particles_.col(i) = mean + lower * standard_normal_state();
    }
    weights_.setConstant(1.0 / static_cast<double>(weights_.size()));
    hold_to_plane();
    refresh_moments();
  }

  void predict(double dt_s) override {
    if (dt_s == 0.0) return;
    const StateCovariance f = settings_.motion.transition(dt_s);
    const Eigen::Matrix<double, kStateSize, 3> gain = settings_.motion.noise_gain(dt_s);
    const double jerk_std = std::sqrt(settings_.motion.jerk_variance_m2ps6);
    for (Eigen::Index i = 0; i < particles_.cols(); ++i) {
      const Eigen::Vector3d jerk(normal_(random_), normal_(random_), normal_(random_));
      particles_.col(i) = f * particles_.col(i) + gain * (jerk_std * jerk);
    }
    hold_to_plane();
    refresh_moments();
  }

  FilterStatus innovation(const DoaMeasurementModel& model, const MeasurementCovariance& noise,
                          Innovation& out) override {
    const Measurement centre = model.predict(mean_);
    Measurement offset = Measurement::Zero();
    for (Eigen::Index i = 0; i < particles_.cols(); ++i) {
      predicted_.col(i) = model.predict(particles_.col(i));
      offset += weights_(i) * model.residual(predicted_.col(i), centre);
    }
    const Measurement z_hat = model.residual(centre + offset, Measurement::Zero());
    MeasurementCovariance s = noise;
    CrossCovariance cross = CrossCovariance::Zero();
    for (Eigen::Index i = 0; i < particles_.cols(); ++i) {
      const Measurement dz = model.residual(predicted_.col(i), z_hat);
      s += weights_(i) * dz * dz.transpose();
      cross += weights_(i) * (particles_.col(i) - mean_) * dz.transpose();
    }
    if (!valid_innovation_covariance(s)) return FilterStatus::failed;
    out = {z_hat, s, cross, noise, &model, std::nullopt};
    return FilterStatus::ok;
  }

  FilterStatus update(const Innovation& innovation, const Measurement& z) override {
    const std::array<Measurement, 1> readings{z};
    const std::array<double, 1> weights{1.0};
    return weigh(innovation, readings, weights, 1);
  }

  // Seed 004: the likelihood of a particle is the mixture over the GCC's top peaks, each a Gaussian
  // about its peak weighted by the peak's GCC value (Fig. 6), so a particle on the true delay keeps
  // its weight when a reflection's peak is the largest.
  FilterStatus update_with_peaks(const Innovation& innovation, const Measurement& z,
                                 const MeasurementPeaks& peaks) override {
    if (!settings_.multipeak_likelihood || peaks.count <= 0) return update(innovation, z);
    const int count = std::min<int>(peaks.count, doa::kMaxConePeaks);
    return weigh(innovation, peaks.value, peaks.weight, count);
  }

  // Seed 004 Step 1: with no initial guess, particles spread uniformly over the region around the
  // array: a disc of max_range_m on the source plane, or a ball without one. The DOA itself is
  // not used: the first update weighs them.
  bool initialise_from_bearing(const BearingLocus& locus) override {
    const OneArrayParams& p = settings_.one_array;
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const Eigen::Vector3d centre = locus.model.centre_m;
    for (Eigen::Index i = 0; i < particles_.cols(); ++i) {
      Eigen::Vector3d position;
      if (p.source_plane_z_m) {
        const double radius = p.max_range_m * std::sqrt(unit(random_));
        const double angle = 2.0 * std::numbers::pi * unit(random_);
        position << centre.x() + radius * std::cos(angle), centre.y() + radius * std::sin(angle),
            *p.source_plane_z_m;
      } else {
        // Uniform in the ball, above the ground (rejection: at most half the ball is lost).
        for (int attempt = 0; attempt < 64; ++attempt) {
          Eigen::Vector3d direction(normal_(random_), normal_(random_), normal_(random_));
          direction.normalize();
          position = centre + p.max_range_m * std::cbrt(unit(random_)) * direction;
          if (position.z() >= locus.min_altitude_m) break;
        }
        position.z() = std::max(position.z(), locus.min_altitude_m);
      }
      StateVector particle = StateVector::Zero();
      particle.segment<3>(StateBlock::position) = position;
      for (int k = 0; k < 3; ++k) {
        particle(StateBlock::velocity + k) = p.velocity_std_mps * normal_(random_);
        particle(StateBlock::acceleration + k) = p.acceleration_std_mps2 * normal_(random_);
      }
      particles_.col(i) = particle;
    }
    weights_.setConstant(1.0 / static_cast<double>(weights_.size()));
    hold_to_plane();
    refresh_moments();
    return true;
  }

  const StateVector& mean() const override { return mean_; }
  const StateCovariance& covariance() const override { return covariance_; }

 private:
  // Multiplies every particle's weight by the likelihood of the readings (a mixture with the
  // given weights; one reading: the plain likelihood) and resamples when the cloud degenerates.
  template <class Readings, class Weights>
  FilterStatus weigh(const Innovation& innovation, const Readings& readings,
                     const Weights& reading_weights, int count) {
    double weight_sum = 0.0;
    for (int k = 0; k < count; ++k) {
      if (!readings[k].allFinite() || !(reading_weights[k] >= 0.0)) return FilterStatus::failed;
      weight_sum += reading_weights[k];
    }
    if (!(weight_sum > 0.0)) return FilterStatus::failed;
    const MeasurementCovariance information = innovation.noise.inverse();
    const int dimension = innovation.dimension();
    if (innovation.model != nullptr) jitter_centre_m_ = innovation.model->centre_m;
    jitter_angle_std_rad_ =
        std::sqrt(dimension == 1 ? innovation.noise(0, 0) : 0.5 * innovation.noise.trace());
    // The same DOA likelihood the Gaussian filters update with (doa_likelihood.hpp), scaled by
    // (2 pi)^(d/2) sqrt(det R) for every particle alike.
    const DoaLikelihood& law = settings_.likelihood;
    const double floor = law.particle_floor(innovation);
    double total = 0.0;
    for (Eigen::Index i = 0; i < particles_.cols(); ++i) {
      double likelihood = 0.0;
      for (int k = 0; k < count; ++k) {
        const Measurement dz = innovation.model != nullptr
                                   ? innovation.model->residual(readings[k], predicted_.col(i))
                                   : azel_residual(readings[k], predicted_.col(i));
        likelihood += reading_weights[k] / weight_sum *
                      law.particle_kernel(dz.dot(information * dz), dimension,
                                          innovation.outlier_probability);
      }
      likelihood += floor;
      weights_(i) *= likelihood;
      total += weights_(i);
    }
    if (!(total > 0.0) || !std::isfinite(total)) {
      weights_.setConstant(1.0 / static_cast<double>(weights_.size()));
      return FilterStatus::failed;
    }
    weights_ /= total;
    const double effective = 1.0 / weights_.squaredNorm();
    if (effective < 0.5 * static_cast<double>(weights_.size())) resample();
    refresh_moments();
    return FilterStatus::ok;
  }

  // The known source plane (issue 15): every particle on it, at rest vertically.
  void hold_to_plane() {
    const OneArrayParams& p = settings_.one_array;
    if (!p.source_plane_z_m) return;
    for (Eigen::Index i = 0; i < particles_.cols(); ++i) {
      particles_(StateBlock::position + 2, i) = *p.source_plane_z_m;
      particles_(StateBlock::velocity + 2, i) = 0.0;
      particles_(StateBlock::acceleration + 2, i) = 0.0;
    }
  }

  StateVector standard_normal_state() {
    StateVector draw;
    for (int k = 0; k < kStateSize; ++k) draw(k) = normal_(random_);
    return draw;
  }

  void resample() {
    const auto count = particles_.cols();
    const double step = 1.0 / static_cast<double>(count);
    double position = std::uniform_real_distribution<double>(0.0, step)(random_);
    double cumulative = weights_(0);
    Eigen::Index source = 0;
    for (Eigen::Index i = 0; i < count; ++i) {
      while (position > cumulative && source + 1 < count) cumulative += weights_(++source);
      resampled_.col(i) = particles_.col(source);
      position += step;
    }
    // Jitter: half the bandwidth of the optimal Gaussian kernel for n = 9 (the full one inflates
    // the cloud by a third at every resampling, too much at 20 DOAs per second).
    const double bandwidth = 0.5 * std::pow(4.0 / ((kStateSize + 2.0) * static_cast<double>(count)),
                                            1.0 / (kStateSize + 4.0));
    StateCovariance spread = covariance_;
    StateCovariance lower;
    if (robust_cholesky(spread, lower) == FilterStatus::failed) lower.setZero();
    if (settings_.local_jitter) {
      // A cloud started with no guess spans a ray's range and both mirror sides: a kernel from its
      // covariance (tens of metres) random-walks it out of the region. Each particle moves by
      // a quarter of the width of the last DOA's likelihood strip at its range instead; velocity
      // and acceleration by the cloud's own (small) spread.
      for (Eigen::Index i = 0; i < count; ++i) {
        StateVector particle = resampled_.col(i);
        const double range_m = (position_of(particle) - jitter_centre_m_).norm();
        const double position_std_m = 0.25 * range_m * jitter_angle_std_rad_;
        for (int k = 0; k < 3; ++k) {
          particle(StateBlock::position + k) += position_std_m * normal_(random_);
          for (int block : {StateBlock::velocity, StateBlock::acceleration}) {
            particle(block + k) += bandwidth *
                                   std::sqrt(std::max(covariance_(block + k, block + k), 0.0)) *
                                   normal_(random_);
          }
        }
        particles_.col(i) = particle;
      }
    } else {
      for (Eigen::Index i = 0; i < count; ++i) {
        particles_.col(i) = resampled_.col(i) + bandwidth * (lower * standard_normal_state());
      }
    }
    hold_to_plane();
    weights_.setConstant(step);
  }

  void refresh_moments() {
    mean_ = particles_ * weights_;
    covariance_.setZero();
    for (Eigen::Index i = 0; i < particles_.cols(); ++i) {
      const StateVector d = particles_.col(i) - mean_;
      covariance_.noalias() += weights_(i) * d * d.transpose();
    }
    symmetrise(covariance_);
    // On the plane the cloud has no vertical spread; the plane's own std keeps the covariance
    // positive definite and honest.
    const OneArrayParams& p = settings_.one_array;
    if (p.source_plane_z_m) {
      const double variance = p.source_plane_std_m * p.source_plane_std_m;
      for (int block : {StateBlock::position, StateBlock::velocity, StateBlock::acceleration})
        covariance_(block + 2, block + 2) += variance;
    }
  }

  FilterSettings settings_;
  Eigen::Matrix<double, kStateSize, Eigen::Dynamic> particles_;
  Eigen::Matrix<double, kStateSize, Eigen::Dynamic> resampled_;
  Eigen::VectorXd weights_;
  Eigen::Matrix<double, kMeasurementSize, Eigen::Dynamic> predicted_;
  StateVector mean_ = StateVector::Zero();
  StateCovariance covariance_ = StateCovariance::Identity();
  std::mt19937_64 random_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  // The last DOA's array centre and angular std, for the local jitter.
  Eigen::Vector3d jitter_centre_m_ = Eigen::Vector3d::Zero();
  double jitter_angle_std_rad_ = 0.01;
};

// Interacting multiple model (Blom & Bar-Shalom 1988; Bar-Shalom, Li & Kirubarajan ch. 11.6):
// one Gaussian filter per jerk level on the same 9-state model, plus optional coordinated-turn
// modes (CoordinatedTurnModel, same state). A drone cruising in gusts has a
// jerk of a fraction of a m/s^3, one entering a tight turn tens of m/s^3: one fixed q either
// follows every wiggle of correlated DOA noise on the straight or lags in the turn. Each predict
// mixes the models' estimates through a Markov chain whose switching probability grows with the
// step (mean sojourn imm_sojourn_s); each update re-weights the modes by their innovation
// likelihood. The tracker sees the moment-matched mixture, for gating and for reports.
class InteractingFilter final : public TrackFilter {
 public:
  using Factory = std::unique_ptr<TrackFilter> (*)(FilterKind, const FilterSettings&);
  InteractingFilter(FilterKind kind, const FilterSettings& settings, Factory make)
      : sojourn_s_(settings.imm_sojourn_s), likelihood_(settings.likelihood) {
    const std::size_t count =
        settings.imm_jerk_std_mps3.size() + settings.imm_turn_rate_std_radps2.size();
    models_.reserve(count);
    FilterSettings single = settings;
    single.imm_jerk_std_mps3.clear();
    single.imm_turn_rate_std_radps2.clear();
    for (double jerk_std : settings.imm_jerk_std_mps3) {
      single.motion_kind = MotionKind::constant_jerk;
      single.motion.jerk_variance_m2ps6 = jerk_std * jerk_std;
      models_.push_back(make(kind, single));
    }
    // Coordinated-turn modes after the jerk levels (mode 0 stays the quietest jerk level).
    for (double turn_rate_std : settings.imm_turn_rate_std_radps2) {
      single.motion_kind = MotionKind::coordinated_turn;
      single.turn.jerk_variance_m2ps6 =
          settings.imm_turn_jerk_std_mps3 * settings.imm_turn_jerk_std_mps3;
      single.turn.turn_rate_variance_rad2ps4 = turn_rate_std * turn_rate_std;
      models_.push_back(make(kind, single));
    }
    probability_.assign(count, 1.0 / static_cast<double>(count));
    predicted_probability_ = probability_;
    log_likelihood_.assign(count, 0.0);
    mixing_.assign(count * count, 0.0);
    mixed_mean_.resize(count);
    mixed_covariance_.resize(count);
    innovations_.resize(count);
    innovation_ok_.assign(count, 0);
  }

  void initialise(const StateVector& mean, const StateCovariance& covariance) override {
    for (auto& model : models_) model->initialise(mean, covariance);
    combine();
  }

  void predict(double dt_s) override {
    if (dt_s == 0.0) return;
    const std::size_t count = models_.size();
    // Markov chain over dt: stay with probability exp(-dt / sojourn), else move to another mode.
    const double stay = std::exp(-std::abs(dt_s) / sojourn_s_);
    const double move = count > 1 ? (1.0 - stay) / static_cast<double>(count - 1) : 0.0;
    for (std::size_t j = 0; j < count; ++j) {
      double total = 0.0;
      for (std::size_t i = 0; i < count; ++i) {
        const double w = (i == j ? stay : move) * probability_[i];
        mixing_[i * count + j] = w;
        total += w;
      }
      predicted_probability_[j] = total;
      for (std::size_t i = 0; i < count; ++i) {
        mixing_[i * count + j] = total > 0.0 ? mixing_[i * count + j] / total : 0.0;
      }
    }
    for (std::size_t j = 0; j < count; ++j) {
      StateVector mean = StateVector::Zero();
      for (std::size_t i = 0; i < count; ++i) mean += mixing_[i * count + j] * models_[i]->mean();
      StateCovariance covariance = StateCovariance::Zero();
      for (std::size_t i = 0; i < count; ++i) {
        const StateVector d = models_[i]->mean() - mean;
        covariance += mixing_[i * count + j] * (models_[i]->covariance() + d * d.transpose());
      }
      mixed_mean_[j] = mean;
      mixed_covariance_[j] = covariance;
    }
    for (std::size_t j = 0; j < count; ++j) {
      models_[j]->initialise(mixed_mean_[j], mixed_covariance_[j]);
      models_[j]->predict(dt_s);
    }
    probability_ = predicted_probability_;
    combine();
  }

  FilterStatus innovation(const DoaMeasurementModel& model, const MeasurementCovariance& noise,
                          Innovation& out) override {
    FilterStatus worst = FilterStatus::ok;
    bool any = false;
    for (std::size_t j = 0; j < models_.size(); ++j) {
      const FilterStatus status = models_[j]->innovation(model, noise, innovations_[j]);
      innovation_ok_[j] = status != FilterStatus::failed;
      if (status == FilterStatus::repaired) worst = FilterStatus::repaired;
      any = any || innovation_ok_[j] != 0;
    }
    if (!any) return FilterStatus::failed;
    noise_ = noise;
    // Mixture moments, angles as wrapped offsets from the most probable mode's prediction.
    std::size_t reference = 0;
    double weight_sum = 0.0;
    for (std::size_t j = 0; j < models_.size(); ++j) {
      if (!innovation_ok_[j]) continue;
      if (!innovation_ok_[reference] || probability_[j] > probability_[reference]) reference = j;
      weight_sum += probability_[j];
    }
    if (!(weight_sum > 0.0)) return FilterStatus::failed;
    if (!mixture_innovation(model, noise, models_, innovations_, innovation_ok_, probability_,
                            weight_sum, reference, mean_, out))
      return FilterStatus::failed;
    return worst;
  }

  FilterStatus update(const Innovation& innovation, const Measurement& z) override {
    if (!z.allFinite()) return FilterStatus::failed;
    // The tracker may have added the DOA's own covariance to S and R after innovation(): add the
    // same to every mode.
    const MeasurementCovariance extra = innovation.noise - noise_;
    FilterStatus worst = FilterStatus::ok;
    double best_log = -std::numeric_limits<double>::infinity();
    bool any = false;
    for (std::size_t j = 0; j < models_.size(); ++j) {
      log_likelihood_[j] = -std::numeric_limits<double>::infinity();
      if (!innovation_ok_[j]) continue;
      Innovation own = innovations_[j];
      own.covariance += extra;
      own.noise = innovation.noise;
      own.outlier_probability = innovation.outlier_probability;
      if (!valid_innovation_covariance(own.covariance)) continue;
      const Measurement residual = own.residual(z);
      const double d2 = residual.dot(own.covariance.ldlt().solve(residual));
      const FilterStatus status = models_[j]->update(own, z);
      if (status == FilterStatus::failed) continue;
      if (status == FilterStatus::repaired) worst = FilterStatus::repaired;
      // Each mode is judged by the same DOA likelihood, on its own prediction: under a robust law
      // one wild DOA does not hand the weight to the widest mode, and a manoeuvre still moves it
      // to the mode that predicted it (each mode weighs the DOA itself in its update, above).
      log_likelihood_[j] =
          -0.5 * likelihood_.assignment_cost(d2, std::log(own.covariance.determinant()),
                                             own.dimension(), own.outlier_probability);
      best_log = std::max(best_log, log_likelihood_[j]);
      any = true;
    }
    if (!any) return FilterStatus::failed;
    double total = 0.0;
    for (std::size_t j = 0; j < models_.size(); ++j) {
      const double w = std::isfinite(log_likelihood_[j])
                           ? probability_[j] * std::exp(log_likelihood_[j] - best_log)
                           : 0.0;
      probability_[j] = w;
      total += w;
    }
    if (!(total > 0.0) || !std::isfinite(total)) {
      probability_.assign(models_.size(), 1.0 / static_cast<double>(models_.size()));
    } else {
      // A floor keeps every mode alive: one that reaches exactly zero can never come back.
      for (double& p : probability_) p = std::max(p / total, kModeFloor);
      double renormalise = 0.0;
      for (double p : probability_) renormalise += p;
      for (double& p : probability_) p /= renormalise;
    }
    combine();
    return worst;
  }

  const StateVector& mean() const override { return mean_; }
  const StateCovariance& covariance() const override { return covariance_; }
  bool add_process_noise(const StateCovariance& extra) override {
    bool any = false;
    for (auto& model : models_) any = model->add_process_noise(extra) || any;
    combine();
    return any;
  }
  int mode_count() const override { return static_cast<int>(models_.size()); }
  double mode_probability(int mode) const override {
    return probability_[static_cast<std::size_t>(mode)];
  }

 private:
  static constexpr double kModeFloor = 1e-6;

  void combine() {
    mean_.setZero();
    for (std::size_t j = 0; j < models_.size(); ++j) mean_ += probability_[j] * models_[j]->mean();
    covariance_.setZero();
    for (std::size_t j = 0; j < models_.size(); ++j) {
      const StateVector d = models_[j]->mean() - mean_;
      covariance_ += probability_[j] * (models_[j]->covariance() + d * d.transpose());
    }
    symmetrise(covariance_);
    // A mixture of positive-definite covariances is positive definite, but not always in
    // floating point when one mode has run far off (spread of 1e16 through a gap of wild DOAs):
    // clamp then (a no-op otherwise).
    StateCovariance lower;
    robust_cholesky(covariance_, lower);
  }

  double sojourn_s_;
  DoaLikelihood likelihood_;
  std::vector<std::unique_ptr<TrackFilter>> models_;
  std::vector<double> probability_;
  std::vector<double> predicted_probability_;
  std::vector<double> log_likelihood_;
  std::vector<double> mixing_;  // [i * count + j]: P(mode i before | mode j after)
  std::vector<StateVector> mixed_mean_;
  std::vector<StateCovariance> mixed_covariance_;
  std::vector<Innovation> innovations_;
  std::vector<char> innovation_ok_;
  MeasurementCovariance noise_ = MeasurementCovariance::Zero();
  StateVector mean_ = StateVector::Zero();
  StateCovariance covariance_ = StateCovariance::Identity();
};

}  // namespace

Measurement Innovation::residual(const Measurement& z) const {
  return model != nullptr ? model->residual(z, predicted) : azel_residual(z, predicted);
}

double Innovation::mahalanobis2(const Measurement& z) const {
  const Measurement residual = this->residual(z);
  return residual.dot(covariance.ldlt().solve(residual));
}

bool is_positive_definite(const StateCovariance& covariance) {
  if (!covariance.allFinite()) return false;
  if (!covariance.isApprox(covariance.transpose(), 1e-9)) return false;
  const Eigen::LLT<StateCovariance> llt(covariance);
  return llt.info() == Eigen::Success;
}

FilterStatus robust_cholesky(StateCovariance& covariance, StateCovariance& lower) {
  if (!covariance.allFinite()) return FilterStatus::failed;
  {
    const Eigen::LLT<StateCovariance> llt(covariance);
    if (llt.info() == Eigen::Success) {
      lower = llt.matrixL();
      return FilterStatus::ok;
    }
  }
  symmetrise(covariance);
  const Eigen::SelfAdjointEigenSolver<StateCovariance> eigen(covariance);
  if (eigen.info() != Eigen::Success) return FilterStatus::failed;
  const double largest = eigen.eigenvalues().cwiseAbs().maxCoeff();
  const double floor = std::max(largest * kEigenFloorRelative, kEigenFloorAbsolute);
  const StateVector clamped = eigen.eigenvalues().cwiseMax(floor);
  covariance = eigen.eigenvectors() * clamped.asDiagonal() * eigen.eigenvectors().transpose();
  symmetrise(covariance);
  const Eigen::LLT<StateCovariance> llt(covariance);
  if (llt.info() != Eigen::Success || !covariance.allFinite()) return FilterStatus::failed;
  lower = llt.matrixL();
  return FilterStatus::repaired;
}

namespace {
std::unique_ptr<TrackFilter> make_single_filter(FilterKind kind, const FilterSettings& settings) {
  switch (kind) {
    case FilterKind::ukf:
      return std::make_unique<UnscentedFilter>(settings, settings.ukf_alpha, settings.ukf_beta,
                                               settings.ukf_kappa);
    case FilterKind::ukf_seed002:
      return std::make_unique<UnscentedFilter>(settings, 1.0, 0.0, 3.0 - kStateSize);
    case FilterKind::ekf:
      return std::make_unique<ExtendedFilter>(settings);
    case FilterKind::particle:
      return std::make_unique<ParticleFilter>(settings);
    case FilterKind::gaussian_sum:
      return make_gaussian_sum_filter(settings);
    case FilterKind::ekf_range_init: {
      FilterSettings own = settings;
      own.range_initialisation = true;
      return std::make_unique<ExtendedFilter>(own);
    }
    case FilterKind::particle_multipeak: {
      FilterSettings own = settings;
      own.multipeak_likelihood = true;
      own.local_jitter = true;
      return std::make_unique<ParticleFilter>(own);
    }
  }
  return nullptr;
}
}  // namespace

bool valid_innovation_covariance(const MeasurementCovariance& s) {
  return s.allFinite() && s(0, 0) > 0.0 && s.determinant() > 0.0;
}

bool mixture_innovation(const DoaMeasurementModel& model, const MeasurementCovariance& noise,
                        std::span<const std::unique_ptr<TrackFilter>> components,
                        std::span<const Innovation> innovations, std::span<const char> ok,
                        std::span<const double> weights, double weight_sum, std::size_t reference,
                        const StateVector& mixture_mean, Innovation& out) {
  const Measurement centre = innovations[reference].predicted;
  Measurement offset = Measurement::Zero();
  for (std::size_t j = 0; j < components.size(); ++j) {
    if (ok[j]) offset += weights[j] / weight_sum * model.residual(innovations[j].predicted, centre);
  }
  const Measurement z_hat = model.residual(centre + offset, Measurement::Zero());
  MeasurementCovariance s = MeasurementCovariance::Zero();
  CrossCovariance cross = CrossCovariance::Zero();
  for (std::size_t j = 0; j < components.size(); ++j) {
    if (!ok[j]) continue;
    const double w = weights[j] / weight_sum;
    const Measurement dz = model.residual(innovations[j].predicted, z_hat);
    s += w * (innovations[j].covariance + dz * dz.transpose());
    cross += w * (innovations[j].cross + (components[j]->mean() - mixture_mean) * dz.transpose());
  }
  s = 0.5 * (s + s.transpose()).eval();
  if (!valid_innovation_covariance(s)) return false;
  out = {z_hat, s, cross, noise, &model, std::nullopt};
  return true;
}

std::unique_ptr<TrackFilter> make_track_filter(FilterKind kind, const FilterSettings& settings) {
  // The particle filters sample one jerk level; the IMM mixes the plain Gaussian filters only (the
  // one-array localisers run one constant-jerk model: static and slow sources).
  const std::size_t modes =
      settings.imm_jerk_std_mps3.size() + settings.imm_turn_rate_std_radps2.size();
  const bool mixable =
      kind == FilterKind::ukf || kind == FilterKind::ukf_seed002 || kind == FilterKind::ekf;
  if (modes >= 2 && mixable) {
    return std::make_unique<InteractingFilter>(kind, settings, &make_single_filter);
  }
  return make_single_filter(kind, settings);
}

}  // namespace dronetrack::fusion
