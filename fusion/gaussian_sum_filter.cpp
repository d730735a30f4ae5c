#include "fusion/gaussian_sum_filter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

namespace dronetrack::fusion {
namespace {
// S must be a finite, positive-definite 2x2 for gating and the weights.
bool valid(const MeasurementCovariance& s) {
  return s.allFinite() && s(0, 0) > 0.0 && s.determinant() > 0.0;
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
  for (int b = 0; b < locus.branch_count; ++b) {
    for (int k = 1; k <= p.hypotheses_per_side; ++k) {
      const double range_m = k * p.hypothesis_spacing_m;
      if (range_m > p.max_range_m) break;
      const auto offset = locus.offset_at(b, range_m);
      if (!offset || count_ >= static_cast<int>(components_.size())) continue;
      // Range std of half the spacing: neighbours meet at 2 sigma, so the sum is near flat in
      // range (seed 003 Fig. 3: a uniform range prior); across, the DOA's own angular std.
      StateVector mean;
      StateCovariance covariance;
      state_at(locus.model.centre_m + *offset,
               range_bearing_covariance(*offset, 0.5 * p.hypothesis_spacing_m, locus.angle_std_rad),
               p, mean, covariance);
      components_[static_cast<std::size_t>(count_)]->initialise(mean, covariance);
      branch_[static_cast<std::size_t>(count_)] = b;
      ++count_;
    }
  }
  if (count_ == 0) return false;
  for (int i = 0; i < count_; ++i) weight_[static_cast<std::size_t>(i)] = 1.0 / count_;  // eq. 6
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
    if (reference < 0 || weight_[j] > weight_[static_cast<std::size_t>(reference)]) reference = i;
    weight_sum += weight_[j];
  }
  if (reference < 0 || !(weight_sum > 0.0)) return FilterStatus::failed;
  noise_ = noise;
  // The moment-matched mixture, angles as wrapped offsets from the heaviest hypothesis's: the
  // gate and the assignment see every hypothesis's spread.
  const Measurement centre = innovations_[static_cast<std::size_t>(reference)].predicted;
  Measurement offset = Measurement::Zero();
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    if (innovation_ok_[j])
      offset += weight_[j] / weight_sum * model.residual(innovations_[j].predicted, centre);
  }
  const Measurement z_hat = model.residual(centre + offset, Measurement::Zero());
  MeasurementCovariance s = MeasurementCovariance::Zero();
  CrossCovariance cross = CrossCovariance::Zero();
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    if (!innovation_ok_[j]) continue;
    const double w = weight_[j] / weight_sum;
    const Measurement dz = model.residual(innovations_[j].predicted, z_hat);
    s += w * (innovations_[j].covariance + dz * dz.transpose());
    cross += w * (innovations_[j].cross + (components_[j]->mean() - mean_) * dz.transpose());
  }
  s = 0.5 * (s + s.transpose()).eval();
  if (!valid(s)) return FilterStatus::failed;
  out = {z_hat, s, cross, noise, &model};
  return worst;
}

FilterStatus GaussianSumFilter::update(const Innovation& innovation, const Measurement& z) {
  if (!z.allFinite()) return FilterStatus::failed;
  // The tracker may have added the DOA's own covariance (and a Student-t reweighting) to S and R
  // after innovation(): every hypothesis takes the same.
  const MeasurementCovariance extra = innovation.noise - noise_;
  FilterStatus worst = FilterStatus::ok;
  double best_log = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    log_likelihood_[j] = -std::numeric_limits<double>::infinity();
    if (!innovation_ok_[j]) continue;
    Innovation own = innovations_[j];
    own.covariance += extra;
    own.noise = innovation.noise;
    if (!valid(own.covariance)) continue;
    const Measurement residual = own.residual(z);
    const double d2 = residual.dot(own.covariance.ldlt().solve(residual));
    const FilterStatus status = components_[j]->update(own, z);
    if (status == FilterStatus::failed) continue;
    if (status == FilterStatus::repaired) worst = FilterStatus::repaired;
    // Eq. 9: the innovation's normal density (the cone's unit pad adds ln 1 = 0).
    log_likelihood_[j] = -0.5 * d2 - 0.5 * std::log(own.covariance.determinant());
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
  for (int i = 0; i < count_; ++i) {
    for (int k = count_ - 1; k > i; --k) {
      const auto a = static_cast<std::size_t>(i);
      const auto b = static_cast<std::size_t>(k);
      const Eigen::Vector3d difference =
          position_of(components_[a]->mean()) - position_of(components_[b]->mean());
      const Eigen::Matrix3d spread = components_[a]->covariance().topLeftCorner<3, 3>() +
                                     components_[b]->covariance().topLeftCorner<3, 3>();
      if (difference.dot(spread.ldlt().solve(difference)) >= settings_.one_array.merge_d2) continue;
      const double total = weight_[a] + weight_[b];
      const StateVector mean =
          (weight_[a] * components_[a]->mean() + weight_[b] * components_[b]->mean()) / total;
      const StateVector da = components_[a]->mean() - mean;
      const StateVector db = components_[b]->mean() - mean;
      const StateCovariance covariance =
          (weight_[a] * (components_[a]->covariance() + da * da.transpose()) +
           weight_[b] * (components_[b]->covariance() + db * db.transpose())) /
          total;
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

void GaussianSumFilter::combine() {
  mean_.setZero();
  for (int i = 0; i < count_; ++i)
    mean_ +=
        weight_[static_cast<std::size_t>(i)] * components_[static_cast<std::size_t>(i)]->mean();
  covariance_.setZero();
  for (int i = 0; i < count_; ++i) {
    const auto j = static_cast<std::size_t>(i);
    const StateVector d = components_[j]->mean() - mean_;
    covariance_ += weight_[j] * (components_[j]->covariance() + d * d.transpose());
  }
  covariance_ = 0.5 * (covariance_ + covariance_.transpose()).eval();
  StateCovariance lower;
  robust_cholesky(covariance_, lower);
}

std::unique_ptr<TrackFilter> make_gaussian_sum_filter(const FilterSettings& settings) {
  return std::make_unique<GaussianSumFilter>(settings);
}

}  // namespace dronetrack::fusion
