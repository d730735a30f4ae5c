#include "sim/propagation.hpp"

#include <algorithm>
#include <cmath>

#include "sim/kernel.hpp"
#include "sim/source_signal.hpp"

namespace dronetrack::sim {
namespace {

// Closer than this the 1/r law would blow up; a real source is not a point.
constexpr double kMinDistance_m = 0.1;

}  // namespace

EmissionSolution solve_emission_time(const Trajectory& trajectory,
                                     const Eigen::Vector3d& receiver_m, double arrival_time_s,
                                     double speed_of_sound_mps, bool mirrored, double guess) {
  return solve_emission_time(
      trajectory, TrajectoryState{receiver_m, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()},
      arrival_time_s, speed_of_sound_mps, mirrored, guess);
}

EmissionSolution solve_emission_time(const Trajectory& trajectory, const TrajectoryState& receiver,
                                     double arrival_time_s, double speed_of_sound_mps,
                                     bool mirrored, double guess) {
  const Eigen::Vector3d& receiver_m = receiver.position_m;
  auto state_at = [&](double t_s) {
    TrajectoryState state = trajectory.at(t_s);
    if (mirrored) {
      state.position_m = mirror_in_ground(state.position_m);
      state.velocity_mps = mirror_in_ground(state.velocity_mps);
    }
    return state;
  };
  // Start from the delay of the source's position at arrival time; Newton on
  // f(t_e) = t_e + |p(t_e) - m| / c - t with f' = 1 + u.v / c (> 0 below Mach 1).
  TrajectoryState state;
  double emission = guess;
  if (!std::isfinite(emission)) {
    state = state_at(arrival_time_s);
    emission = arrival_time_s - (state.position_m - receiver_m).norm() / speed_of_sound_mps;
  }
  EmissionSolution solution;
  for (int iteration = 0; iteration < 30; ++iteration) {
    state = state_at(emission);
    const Eigen::Vector3d offset = state.position_m - receiver_m;
    const double distance = offset.norm();
    const double radial_speed = distance > 0.0 ? offset.dot(state.velocity_mps) / distance : 0.0;
    const double slope = 1.0 + radial_speed / speed_of_sound_mps;
    const double residual = emission + distance / speed_of_sound_mps - arrival_time_s;
    const double step = residual / slope;
    emission -= step;
    // d/dt of t_e + |p(t_e) - m(t)| / c = t; a fixed mic gives exactly 1 / slope as before.
    const double receiver_closing_speed =
        distance > 0.0 ? offset.dot(receiver.velocity_mps) / distance : 0.0;
    solution.derivative = (1.0 + receiver_closing_speed / speed_of_sound_mps) / slope;
    solution.distance_m = distance;
    if (std::abs(step) < 1e-14 * std::max(1.0, std::abs(arrival_time_s))) break;
  }
  solution.emission_time_s = emission;
  return solution;
}

EmissionGrid::EmissionGrid(const Trajectory& trajectory, const Receiver& receiver, bool mirrored,
                           double speed_of_sound_mps, double begin_s, double end_s, double step_s,
                           double recording_delay_s)
    : begin_s_(begin_s), step_s_(step_s) {
  const auto intervals = static_cast<std::size_t>(std::ceil((end_s - begin_s) / step_s - 1e-9));
  const std::size_t points = std::max<std::size_t>(intervals, 1) + 1;
  emission_time_s_.resize(points);
  derivative_.resize(points);
  distance_m_.resize(points);
  for (std::size_t k = 0; k < points; ++k) {
    const double t_s = begin_s + static_cast<double>(k) * step_s - recording_delay_s;
    // The previous point extrapolated is within nanoseconds: Newton then needs one or two steps.
    const double guess = k == 0 ? std::numeric_limits<double>::quiet_NaN()
                                : emission_time_s_[k - 1] + derivative_[k - 1] * step_s;
    const EmissionSolution solution =
        solve_emission_time(trajectory, receiver.at(t_s), t_s, speed_of_sound_mps, mirrored, guess);
    emission_time_s_[k] = solution.emission_time_s;
    derivative_[k] = solution.derivative;
    distance_m_[k] = std::max(solution.distance_m, kMinDistance_m);
  }
}

double EmissionGrid::emission_time(double arrival_time_s) const {
  const double position = (arrival_time_s - begin_s_) / step_s_;
  const auto k = std::min(static_cast<std::size_t>(std::max(position, 0.0)), intervals() - 1);
  const double u = position - static_cast<double>(k);
  const double y0 = emission_time_s_[k];
  const double y1 = emission_time_s_[k + 1];
  const double m0 = derivative_[k] * step_s_;
  const double m1 = derivative_[k + 1] * step_s_;
  const double difference = y1 - y0;
  return y0 +
         u * (m0 + u * ((3.0 * difference - 2.0 * m0 - m1) + u * (-2.0 * difference + m0 + m1)));
}

double EmissionGrid::distance_m(double arrival_time_s) const {
  const double position = (arrival_time_s - begin_s_) / step_s_;
  const auto k = std::min(static_cast<std::size_t>(std::max(position, 0.0)), intervals() - 1);
  const double u = position - static_cast<double>(k);
  return distance_m_[k] + u * (distance_m_[k + 1] - distance_m_[k]);
}

void EmissionGrid::accumulate(const SourceBuffer& source, double gain, double sample_rate_hz,
                              std::size_t frame_begin, std::size_t frame_end, float* out,
                              std::size_t stride) const {
  const InterpolationKernel& kernel = source_kernel();
  const double samples_per_step = step_s_ * sample_rate_hz;
  const double offset_samples = begin_s_ * sample_rate_hz;  // grid start in output samples
  const double first_interval =
      std::floor((static_cast<double>(frame_begin) - offset_samples) / samples_per_step) - 1.0;
  const auto k_begin = static_cast<std::size_t>(std::max(0.0, first_interval));
  for (std::size_t k = k_begin; k < intervals(); ++k) {
    // Output samples whose time falls in [t_k, t_k+1).
    const double first = offset_samples + static_cast<double>(k) * samples_per_step;
    const double last = first + samples_per_step;
    const auto n_begin =
        std::max(frame_begin, static_cast<std::size_t>(std::max(0.0, std::ceil(first - 1e-9))));
    const auto n_end =
        std::min(frame_end, static_cast<std::size_t>(std::max(0.0, std::ceil(last - 1e-9))));
    if (first >= static_cast<double>(frame_end)) break;
    if (n_begin >= n_end) continue;
    // The Hermite cubic in source-sample units, as a polynomial in u in [0, 1).
    const double y0 = source.position(emission_time_s_[k]);
    const double y1 = source.position(emission_time_s_[k + 1]);
    const double m0 = derivative_[k] * step_s_ * source.rate_hz;
    const double m1 = derivative_[k + 1] * step_s_ * source.rate_hz;
    const double difference = y1 - y0;
    const double c2 = 3.0 * difference - 2.0 * m0 - m1;
    const double c3 = -2.0 * difference + m0 + m1;
    const double gain0 = gain / distance_m_[k];
    const double gain_slope = gain / distance_m_[k + 1] - gain0;
    const double inverse_span = 1.0 / samples_per_step;
    for (std::size_t n = n_begin; n < n_end; ++n) {
      const double u = (static_cast<double>(n) - first) * inverse_span;
      const double position = y0 + u * (m0 + u * (c2 + u * c3));
      const auto value = kernel.at(source.samples.data(), position);
      out[n * stride] += static_cast<float>(gain0 + u * gain_slope) * value;
    }
  }
}

}  // namespace dronetrack::sim
