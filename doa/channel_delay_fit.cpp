#include "doa/channel_delay_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Cholesky>

namespace dronetrack::doa {

namespace {
// The fit's floor on a pair delay's noise: a sub-sample GCC estimate is not better.
constexpr double kMinDelayNoise_s = 2e-6;
}  // namespace

ChannelDelayFit::ChannelDelayFit(const PairBySpace& pair_vectors_m, int channels,
                                 double speed_of_sound_mps, double hop_s, const Settings& settings)
    : channels_(channels),
      parameters_(channels + 1),
      speed_of_sound_mps_(speed_of_sound_mps),
      settings_(settings),
      forgetting_(std::exp(-hop_s / settings.window_s)),
      sector_of_(settings.sectors),
      geometry_(pair_vectors_m) {
  const int pairs = static_cast<int>(pair_vectors_m.rows());
  difference_.setZero(pairs, channels_);
  int p = 0;
  for (int i = 0; i < channels_; ++i)
    for (int j = i + 1; j < channels_; ++j, ++p) {
      difference_(p, i) = 1.0;
      difference_(p, j) = -1.0;
    }
  const Eigen::Matrix3d normal = geometry_.transpose() * geometry_;
  geometry_inverse_ = normal.inverse() * geometry_.transpose();
  slowness_of_delays_ = geometry_inverse_ * difference_;
  out_of_range_ = difference_ - geometry_ * slowness_of_delays_;
  // Sum over pairs of |p_j - p_i|^2 is n times the sum of the mics' squared distances from
  // their centroid: the rms radius without the mics themselves.
  const double radius_m = std::sqrt(geometry_.squaredNorm()) / channels_;
  scale_length_s_ = radius_m / speed_of_sound_mps_;

  Sector empty;
  empty.information.setZero(parameters_, parameters_);
  empty.score.setZero(parameters_);
  sectors_.assign(static_cast<std::size_t>(settings_.sectors), empty);
  estimate_.setZero(parameters_);
  delays_.assign(static_cast<std::size_t>(channels_),
                 {0.0, std::numeric_limits<double>::infinity()});
  tdoas_.setZero(pairs);
  misfit_.setZero(pairs);
  jacobian_.setZero(pairs, parameters_);
  system_.setZero(parameters_, parameters_);
  meat_.setZero(parameters_, parameters_);
  vector_.setZero(parameters_);
  sector_score_.setZero(parameters_);
}

double ChannelDelayFit::scale_error() const { return estimate_(channels_) / scale_length_s_; }

void ChannelDelayFit::decay(Sector& sector) const {
  if (sector.updated_frame == frame_index_) return;
  const double factor =
      std::pow(forgetting_, static_cast<double>(frame_index_ - sector.updated_frame));
  sector.information *= factor;
  sector.score *= factor;
  sector.frames *= factor;
  sector.updated_frame = frame_index_;
}

// tau = G s + D d with s = u (1 + k) / c: the slowness of the delays freed of the current
// estimate gives the direction u, and what the estimate's model leaves of the delays is the
// misfit r. Around the estimate r = J (x - x_est), J = [E + (G u)(F^T u)^T, G u / R] (E: the part
// of D outside G's range, F = G^+ D; a delay's part inside the range moves the slowness, and only
// its radial component, u . F d, is not absorbed by the direction; the scale parameter is k R / c
// in seconds, R the array's rms radius), so the sector gains J^T J and J^T (r + J x_est).
bool ChannelDelayFit::observe(const PairVector& tdoas_s) {
  ++frame_index_;
  frames_ *= forgetting_;
  square_sum_ *= forgetting_;
  tdoas_.noalias() = tdoas_s - difference_ * estimate_.head(channels_);
  const Eigen::Vector3d slowness = geometry_inverse_ * tdoas_;
  const double length = slowness.norm() * speed_of_sound_mps_;
  if (!(length > 0.5 && length < 1.5)) return false;  // not one plane wave: a stray frame
  const Eigen::Vector3d direction = slowness.normalized();
  const double scale = 1.0 + scale_error();
  misfit_.noalias() = tdoas_ - geometry_ * (direction * (scale / speed_of_sound_mps_));
  square_sum_ += misfit_.squaredNorm();
  frames_ += 1.0;
  const PairVector radial = geometry_ * direction;
  jacobian_.leftCols(channels_) = out_of_range_;
  jacobian_.leftCols(channels_).noalias() +=
      radial * (slowness_of_delays_.transpose() * direction).transpose();
  jacobian_.col(channels_) = radial / (speed_of_sound_mps_ * scale_length_s_);
  misfit_.noalias() += jacobian_ * estimate_;
  Sector& sector = sectors_[static_cast<std::size_t>(sector_of_.nearest(direction))];
  decay(sector);
  sector.information.noalias() += jacobian_.transpose() * jacobian_;
  sector.score.noalias() += jacobian_.transpose() * misfit_;
  sector.frames += 1.0;
  return true;
}

// The estimate: the sectors' information summed, with a weak prior on each delay and on the
// scale (what the directions seen do not reveal stays at 0) and the delays' mean held at 0 (a
// delay common to all channels is the clock's). Its covariance: A^-1 (sum over sectors of
// g g^T + the prior's) A^-1, g a sector's score at the estimate, scaled by K / (K - p) for K
// sectors and p free parameters (Liang and Zeger's cluster-robust estimator): a bias shared by a
// sector's frames shows as a score no frame count can shrink.
void ChannelDelayFit::solve() {
  system_.setZero();
  vector_.setZero();
  int seen = 0;
  int clusters = 0;
  for (Sector& sector : sectors_) {
    decay(sector);
    if (!(sector.frames > 0.0)) continue;
    ++clusters;
    if (sector.frames >= settings_.min_sector_frames) ++seen;
    system_ += sector.information;
    vector_ += sector.score;
  }
  sectors_seen_ = seen;
  const auto n = static_cast<double>(channels_);
  const double pairs = static_cast<double>(geometry_.rows());
  const double noise_s2 =
      frames_ > 0.0 ? std::max(kMinDelayNoise_s * kMinDelayNoise_s, square_sum_ / (frames_ * pairs))
                    : kMinDelayNoise_s * kMinDelayNoise_s;
  const double delay_prior_s = 1e-6 * settings_.prior_us;
  const double scale_prior_s = settings_.scale_prior * scale_length_s_;
  ParameterVector prior =
      ParameterVector::Constant(parameters_, 1.0 / (delay_prior_s * delay_prior_s));
  prior(channels_) = 1.0 / (scale_prior_s * scale_prior_s);
  prior *= noise_s2;
  system_.diagonal() += prior;
  const double gauge = std::max(1.0, system_.topLeftCorner(channels_, channels_).trace()) / (n * n);
  system_.topLeftCorner(channels_, channels_).array() += gauge;
  const Eigen::LDLT<ParameterMatrix> solver(system_);
  estimate_ = solver.solve(vector_);

  meat_.setZero();
  for (const Sector& sector : sectors_) {
    if (!(sector.frames > 0.0)) continue;
    sector_score_.noalias() = sector.score - sector.information * estimate_;
    meat_.noalias() += sector_score_ * sector_score_.transpose();
  }
  const int free = free_parameters();
  const bool enough = clusters > free;
  if (enough) meat_ *= static_cast<double>(clusters) / (clusters - free);
  meat_.diagonal() += noise_s2 * prior;
  const ParameterMatrix half = solver.solve(meat_);
  const ParameterMatrix covariance = solver.solve(half.transpose());

  // Offsets against the median channel (the mean of the middle two for an even count).
  // An insertion sort: at most 8 channels (std::sort's unrolled insertion trips GCC 12's
  // -Warray-bounds on so short an array).
  std::array<int, kMaxFitChannels> order{};
  for (int c = 0; c < channels_; ++c) {
    int at = c;
    for (; at > 0 && estimate_(order[static_cast<std::size_t>(at - 1)]) > estimate_(c); --at)
      order[static_cast<std::size_t>(at)] = order[static_cast<std::size_t>(at - 1)];
    order[static_cast<std::size_t>(at)] = c;
  }
  const int upper = order[static_cast<std::size_t>(channels_ / 2)];
  const int lower = order[static_cast<std::size_t>((channels_ - 1) / 2)];
  const double median_s = 0.5 * (estimate_(upper) + estimate_(lower));
  for (int c = 0; c < channels_; ++c) {
    vector_.setZero();
    vector_(c) += 1.0;
    vector_(upper) -= 0.5;
    vector_(lower) -= 0.5;
    const double variance = vector_.dot(covariance * vector_);
    ChannelDelay& delay = delays_[static_cast<std::size_t>(c)];
    delay.offset_us = 1e6 * (estimate_(c) - median_s);
    delay.std_us = enough && variance >= 0.0 ? 1e6 * std::sqrt(variance)
                                             : std::numeric_limits<double>::infinity();
  }
}

}  // namespace dronetrack::doa
