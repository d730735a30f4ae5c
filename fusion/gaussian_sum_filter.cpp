#include "fusion/gaussian_sum_filter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

namespace dronetrack::fusion {
namespace {
// ln det of a covariance's position block (-inf when it is not positive definite).
double log_det_position(const StateCovariance& covariance) {
  const Eigen::LLT<Eigen::Matrix3d> llt(covariance.topLeftCorner<3, 3>());
  if (llt.info() != Eigen::Success) return -std::numeric_limits<double>::infinity();
  return 2.0 * llt.matrixLLT().diagonal().array().log().sum();
}
}  // namespace

GaussianSumFilter::GaussianSumFilter(const FilterSettings& settings) : settings_(settings) {
  // Two branches at most (a ray and its mirror, or a cone's two sides on the plane).
  const auto capacity =
      static_cast<std::size_t>(2 * std::max(1, settings.one_array.hypotheses_per_side));
  FilterSettings component = settings;
  component.imm_jerk_std_mps3.clear();
  component.imm_turn_rate_std_radps2.clear();
  component.motion_kind = MotionKind::constant_jerk;
  component.range_initialisation = false;
  components_.reserve(capacity);
  for (std::size_t i = 0; i < capacity; ++i)
    components_.push_back(make_track_filter(FilterKind::ekf, component));
  weight_.assign(capacity, 0.0);
  effective_.assign(capacity, 0.0);
  branch_.assign(capacity, 0);
  log_likelihood_.assign(capacity, 0.0);
  innovations_.resize(capacity);
  innovation_ok_.assign(capacity, 0);
}

void GaussianSumFilter::initialise(const StateVector& mean, const StateCovariance& covariance) {
  components_[0]->initialise(mean, covariance);
  weight_[0] = 1.0;
  branch_[0] = 0;
  count_ = 1;
  combine();
}

bool GaussianSumFilter::initialise_from_bearing(const BearingLocus& locus) {
  const OneArrayParams& p = settings_.one_array;
  count_ = 0;
  double total = 0.0;
  for (int b = 0; b < locus.branch_count; ++b) {
    double range_m = p.hypothesis_spacing_m;
    for (int k = 1; k <= p.hypotheses_per_side && range_m <= p.max_range_m; ++k) {
      // Evenly spaced near the array, geometrically beyond (fusion_params.hpp).
      const double gap_m =
          std::max(p.hypothesis_spacing_m, (p.hypothesis_range_ratio - 1.0) * range_m);
      const auto offset = locus.offset_at(b, range_m);
      range_m += gap_m;
      if (!offset || count_ >= static_cast<int>(components_.size())) continue;
      // Range std of half the gap: neighbours meet at 2 sigma, and a weight in proportion to the
      // gap: the sum is near flat in range (seed 003 Fig. 3: a uniform range prior; eq. 6's equal
      // weights when evenly spaced); across, the DOA's own angular std.
      StateVector mean;
      StateCovariance covariance;
      state_at(locus.model.centre_m + *offset,
               range_bearing_covariance(*offset, 0.5 * gap_m, locus.angle_std_rad), p, mean,
               covariance);
      const auto j = static_cast<std::size_t>(count_);
      components_[j]->initialise(mean, covariance);
      branch_[j] = b;
      weight_[j] = gap_m;
      total += gap_m;
      ++count_;
    }
  }
  if (count_ == 0) return false;
  for (int i = 0; i < count_; ++i) weight_[static_cast<std::size_t>(i)] /= total;
  combine();
  return true;
}

void GaussianSumFilter::predict(double dt_s) {
  if (dt_s == 0.0) return;
  for (int i = 0; i < count_; ++i) components_[static_cast<std::size_t>(i)]->predict(dt_s);
  prune_and_merge();  // hypotheses that were apart can meet while they move
  combine();
}

FilterStatus GaussianSumFilter::innovation(const DoaMeasurementModel& model,
                                           const MeasurementCovariance& noise, Innovation& out) {
  FilterStatus worst = FilterStatus::ok;
  int reference = -1;
  double weight_sum = 0.0;
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    const FilterStatus status = components_[j]->innovation(model, noise, innovations_[j]);
    innovation_ok_[j] = status != FilterStatus::failed;
    if (!innovation_ok_[j]) continue;
    if (status == FilterStatus::repaired) worst = FilterStatus::repaired;
    if (reference < 0 || effective_[j] > effective_[static_cast<std::size_t>(reference)])
      reference = i;
    weight_sum += effective_[j];
  }
  if (reference < 0 || !(weight_sum > 0.0)) return FilterStatus::failed;
  noise_ = noise;
  // The moment-matched mixture, angles as wrapped offsets from the heaviest hypothesis's: the
  // gate and the assignment see every hypothesis's spread.
  const auto live = static_cast<std::size_t>(count_);
  if (!mixture_innovation(model, noise, std::span(components_).first(live),
                          std::span(innovations_).first(live), innovation_ok_, effective_,
                          weight_sum, static_cast<std::size_t>(reference), mean_, out))
    return FilterStatus::failed;
  return worst;
}

FilterStatus GaussianSumFilter::update(const Innovation& innovation, const Measurement& z) {
  if (!z.allFinite()) return FilterStatus::failed;
  // The tracker may have added the DOA's own covariance to S and R after innovation(): every
  // hypothesis takes the same.
  const MeasurementCovariance extra = innovation.noise - noise_;
  if (!valid_innovation_covariance(innovation.covariance)) return FilterStatus::failed;
  const Eigen::LDLT<MeasurementCovariance> common(innovation.covariance);
  // A constant for every hypothesis, but the outlier part's density over the Gaussian part's
  // depends on it when the law spreads its outliers (doa_likelihood.hpp).
  const double common_log_det = std::log(innovation.covariance.determinant());
  FilterStatus worst = FilterStatus::ok;
  double best_log = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    log_likelihood_[j] = -std::numeric_limits<double>::infinity();
    if (!innovation_ok_[j]) continue;
    Innovation own = innovations_[j];
    own.covariance += extra;
    own.noise = innovation.noise;
    own.outlier_probability = innovation.outlier_probability;
    if (!valid_innovation_covariance(own.covariance)) continue;
    // Each hypothesis's own prediction, judged on the mixture's common spread (see below).
    const Measurement residual = own.residual(z);
    const double d2 = residual.dot(common.solve(residual));
    const FilterStatus status = components_[j]->update(own, z);
    if (status == FilterStatus::failed) continue;
    if (status == FilterStatus::repaired) worst = FilterStatus::repaired;
    // Eq. 9 with the mixture's S for every hypothesis: N(nu_i; 0, S), S common. With each
    // hypothesis's own S_i the term ln det S_i ranks the ranges by the bearing spread their motion
    // prior predicts (a metric velocity and jerk prior is a wide angular one near the array, a
    // narrow one far out): from a static array, whose bearings leave the range open, that is the
    // prior choosing the range, not the data. On a common S a hypothesis loses weight only by
    // predicting the DOA worse than the others (the mirror side after a turn, a range the
    // platform's motion rules out).
    // Under the settings' DOA likelihood, as the IMM weighs its modes.
    const DoaLikelihood& law = settings_.likelihood;
    log_likelihood_[j] =
        -0.5 * law.assignment_cost(d2, common_log_det, own.dimension(), own.outlier_probability);
    if (settings_.one_array.own_spread_weights)  // seed 003's eq. 9 as printed
      log_likelihood_[j] =
          -0.5 * law.assignment_cost(residual.dot(own.covariance.ldlt().solve(residual)),
                                     std::log(own.covariance.determinant()), own.dimension(),
                                     own.outlier_probability);
    best_log = std::max(best_log, log_likelihood_[j]);
  }
  if (!std::isfinite(best_log)) return FilterStatus::failed;
  double total = 0.0;
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    weight_[j] = std::isfinite(log_likelihood_[j])
                     ? weight_[j] * std::exp(log_likelihood_[j] - best_log)
                     : 0.0;
    total += weight_[j];
  }
  if (!(total > 0.0) || !std::isfinite(total)) return FilterStatus::failed;
  for (int i = 0; i < count_; ++i) weight_[static_cast<std::size_t>(i)] /= total;
  prune_and_merge();
  combine();
  return worst;
}

const StateVector& GaussianSumFilter::hypothesis_mean(int hypothesis) const {
  return components_[static_cast<std::size_t>(hypothesis)]->mean();
}

double GaussianSumFilter::branch_weight(int branch) const {
  double total = 0.0;
  for (int i = 0; i < count_; ++i)
    if (branch_[static_cast<std::size_t>(i)] == branch)
      total += weight_[static_cast<std::size_t>(i)];
  return total;
}

void GaussianSumFilter::remove(int hypothesis) {
  const auto j = static_cast<std::size_t>(hypothesis);
  const auto last = static_cast<std::size_t>(count_ - 1);
  std::swap(components_[j], components_[last]);  // a pointer swap: no allocation
  std::swap(weight_[j], weight_[last]);
  std::swap(effective_[j], effective_[last]);
  std::swap(branch_[j], branch_[last]);
  std::swap(innovations_[j], innovations_[last]);
  std::swap(innovation_ok_[j], innovation_ok_[last]);
  --count_;
}

void GaussianSumFilter::prune_and_merge() {
  // Eq. 10: keep a_i > gamma / N.
  const double threshold = settings_.one_array.prune_gamma / std::max(count_, 1);
  for (int i = count_ - 1; i >= 0 && count_ > 1; --i) {
    if (weight_[static_cast<std::size_t>(i)] < threshold) remove(i);
  }
  // Runnalls' merge cost (fusion_params.hpp, merge_d2), position block.
  const double max_cost = std::log1p(0.25 * settings_.one_array.merge_d2);
  for (int i = 0; i < count_; ++i) {
    for (int k = count_ - 1; k > i; --k) {
      const auto a = static_cast<std::size_t>(i);
      const auto b = static_cast<std::size_t>(k);
      const double total = weight_[a] + weight_[b];
      const StateVector mean =
          (weight_[a] * components_[a]->mean() + weight_[b] * components_[b]->mean()) / total;
      const StateVector da = components_[a]->mean() - mean;
      const StateVector db = components_[b]->mean() - mean;
      const StateCovariance covariance =
          (weight_[a] * (components_[a]->covariance() + da * da.transpose()) +
           weight_[b] * (components_[b]->covariance() + db * db.transpose())) /
          total;
      const double log_det_a = log_det_position(components_[a]->covariance());
      const double log_det_b = log_det_position(components_[b]->covariance());
      const double cost =
          log_det_position(covariance) - (weight_[a] * log_det_a + weight_[b] * log_det_b) / total;
      if (!(cost < max_cost)) continue;
      components_[a]->initialise(mean, covariance);
      weight_[a] = total;
      remove(k);
    }
  }
  double total = 0.0;
  for (int i = 0; i < count_; ++i) total += weight_[static_cast<std::size_t>(i)];
  if (total > 0.0)
    for (int i = 0; i < count_; ++i) weight_[static_cast<std::size_t>(i)] /= total;
}

double GaussianSumFilter::speed_plausibility(int hypothesis) const {
  const double max_speed_mps = settings_.one_array.max_speed_mps;
  if (!(max_speed_mps > 0.0)) return 1.0;
  const TrackFilter& component = *components_[static_cast<std::size_t>(hypothesis)];
  const Eigen::Vector3d velocity = velocity_of(component.mean());
  const double speed_mps = velocity.norm();
  if (!(speed_mps > max_speed_mps)) return 1.0;
  // P(|v| <= max) along the mean velocity's direction (1-D: the spread across it only adds speed).
  const Eigen::Vector3d along = velocity / speed_mps;
  const double variance = along.dot(
      component.covariance().block<3, 3>(StateBlock::velocity, StateBlock::velocity) * along);
  if (!(variance > 0.0)) return 0.0;
  return 0.5 * std::erfc((speed_mps - max_speed_mps) / std::sqrt(2.0 * variance));
}

void GaussianSumFilter::combine() {
  // The reported mixture: each weight times its speed's plausibility (fusion_params.hpp,
  // max_speed_mps); the stored weights stay the bearings' alone.
  double total = 0.0;
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    effective_[j] = weight_[j] * speed_plausibility(i);
    total += effective_[j];
  }
  // Every hypothesis too fast (a source faster than the bound): the bearings' weights.
  const bool bounded = total > 1e-12;
  if (!bounded) total = 0.0;
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    if (!bounded) effective_[j] = weight_[j];
    if (!bounded) total += effective_[j];
  }
  for (int i = 0; i < count_; ++i) effective_[static_cast<std::size_t>(i)] /= total;
  mean_.setZero();
  for (int i = 0; i < count_; ++i)
    mean_ +=
        effective_[static_cast<std::size_t>(i)] * components_[static_cast<std::size_t>(i)]->mean();
  covariance_.setZero();
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    const StateVector d = components_[j]->mean() - mean_;
    covariance_ += effective_[j] * (components_[j]->covariance() + d * d.transpose());
  }
  covariance_ = 0.5 * (covariance_ + covariance_.transpose()).eval();
  StateCovariance lower;
  robust_cholesky(covariance_, lower);
}

std::unique_ptr<TrackFilter> make_gaussian_sum_filter(const FilterSettings& settings) {
  return std::make_unique<GaussianSumFilter>(settings);
}

}  // namespace dronetrack::fusion
