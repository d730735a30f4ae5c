#include "calib/reference_track.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace dronetrack::calib {

ReferenceTrack::ReferenceTrack(std::vector<ReferenceSample> samples, double max_gap_s)
    : samples_(std::move(samples)), max_gap_s_(max_gap_s) {
  if (samples_.size() < 2) throw std::invalid_argument("a reference track needs 2 samples");
  for (std::size_t i = 1; i < samples_.size(); ++i) {
    if (!(samples_[i].time_s > samples_[i - 1].time_s))
      throw std::invalid_argument("reference sample times must increase");
  }
}

std::optional<ReferenceBracket> ReferenceTrack::bracket(double time_s) const {
  if (!(time_s >= start_s() && time_s <= end_s())) return std::nullopt;
  const auto after = std::upper_bound(
      samples_.begin(), samples_.end(), time_s,
      [](double time, const ReferenceSample& sample) { return time < sample.time_s; });
  // The last sample itself belongs to the last interval.
  const std::size_t upper = std::min<std::size_t>(
      static_cast<std::size_t>(after - samples_.begin()), samples_.size() - 1);
  const std::size_t lower = upper - 1;
  const double span_s = samples_[upper].time_s - samples_[lower].time_s;
  if (span_s > max_gap_s_) return std::nullopt;
  return ReferenceBracket{static_cast<int>(lower), (time_s - samples_[lower].time_s) / span_s};
}

Eigen::Vector3d ReferenceTrack::position_at(const ReferenceBracket& bracket,
                                            const std::vector<Eigen::Vector3d>& positions) const {
  const auto i = static_cast<std::size_t>(bracket.index);
  return (1.0 - bracket.weight) * positions[i] + bracket.weight * positions[i + 1];
}

Eigen::Vector3d ReferenceTrack::velocity_mps(double time_s, double half_window_s) const {
  const auto first = std::lower_bound(
      samples_.begin(), samples_.end(), time_s - half_window_s,
      [](const ReferenceSample& sample, double time) { return sample.time_s < time; });
  double count = 0.0, sum_t = 0.0, sum_tt = 0.0;
  Eigen::Vector3d sum_p = Eigen::Vector3d::Zero(), sum_tp = Eigen::Vector3d::Zero();
  for (auto it = first; it != samples_.end() && it->time_s <= time_s + half_window_s; ++it) {
    const double t = it->time_s - time_s;
    count += 1.0;
    sum_t += t;
    sum_tt += t * t;
    sum_p += it->position_m;
    sum_tp += t * it->position_m;
  }
  const double denominator = count * sum_tt - sum_t * sum_t;
  if (count < 2.0 || !(denominator > 0.0)) return Eigen::Vector3d::Zero();
  return (count * sum_tp - sum_t * sum_p) / denominator;
}

std::optional<double> ReferenceTrack::emission_time_s(
    double arrival_s, const Eigen::Vector3d& listener_m, double speed_of_sound_mps,
    const std::vector<Eigen::Vector3d>& positions) const {
  double emission_s = arrival_s;
  for (int iteration = 0; iteration < 20; ++iteration) {
    // Clamped while iterating: the first guess (no delay) may lie past the track's end.
    const double clamped_s = std::clamp(emission_s, start_s(), end_s());
    const auto where = bracket(clamped_s);
    if (!where) return std::nullopt;
    const double next_s =
        arrival_s - (position_at(*where, positions) - listener_m).norm() / speed_of_sound_mps;
    const bool converged = std::abs(next_s - emission_s) < 1e-9;
    emission_s = next_s;
    if (converged) break;
  }
  if (!bracket(emission_s)) return std::nullopt;
  return emission_s;
}

}  // namespace dronetrack::calib
