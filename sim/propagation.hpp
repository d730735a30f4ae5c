#pragma once
// Sound travelling from a moving point source to a microphone, fixed or carried by a moving
// array. The sound arriving at time t left the source at the emission time t_e solving
// t_e + |p(t_e) - m(t)| / c = t, with m(t) where the mic is at reception; Doppler shift (of both
// ends) and the changing delay follow from that alone. Solving it per output sample is too slow
// (tens of millions of samples per scene), so it is solved exactly on a 1 ms grid together with
// its derivative dt_e/dt = (1 + u.v_m / c) / (1 + u.v_s / c) (u: unit vector from the mic to the
// source at emission), and cubic Hermite interpolation fills in between: for trajectories made of
// lines and arcs the error stays in the nanoseconds (bounded in tests/sim/propagation_test.cpp
// against a per-sample solve).
#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "sim/array_motion.hpp"
#include "sim/trajectory.hpp"

namespace dronetrack::sim {

struct SourceBuffer;

// Where a microphone is at any time: a fixed site point, or a point fixed in a moving array's
// frame (the motion must outlive the receiver).
class Receiver {
 public:
  static Receiver fixed(const Eigen::Vector3d& site_m) { return Receiver(site_m, nullptr); }
  static Receiver carried(const ArrayMotion& motion, const Eigen::Vector3d& array_point_m) {
    return Receiver(array_point_m, &motion);
  }
  TrajectoryState at(double t_s) const {
    if (!motion_)
      return TrajectoryState{point_m_, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    return motion_->point_state(point_m_, t_s);
  }

 private:
  Receiver(const Eigen::Vector3d& point_m, const ArrayMotion* motion)
      : point_m_(point_m), motion_(motion) {}
  Eigen::Vector3d point_m_;  // site frame if fixed, array frame if carried
  const ArrayMotion* motion_;
};

// The image source below a reflecting ground at z = 0.
inline Eigen::Vector3d mirror_in_ground(const Eigen::Vector3d& point) {
  return {point.x(), point.y(), -point.z()};
}

struct EmissionSolution {
  double emission_time_s = 0.0;
  double derivative = 1.0;  // dt_e / dt
  double distance_m = 0.0;  // |p(t_e) - m|
};

// Newton's method to ~1e-14 s relative. `receiver`: the mic's position and velocity at the
// arrival time. `mirrored`: the ground image of the source. `guess`: a starting emission time
// (NaN: start from the delay of the source's position at arrival).
EmissionSolution solve_emission_time(const Trajectory& trajectory, const TrajectoryState& receiver,
                                     double arrival_time_s, double speed_of_sound_mps,
                                     bool mirrored = false,
                                     double guess = std::numeric_limits<double>::quiet_NaN());
// A fixed mic.
EmissionSolution solve_emission_time(const Trajectory& trajectory,
                                     const Eigen::Vector3d& receiver_m, double arrival_time_s,
                                     double speed_of_sound_mps, bool mirrored = false,
                                     double guess = std::numeric_limits<double>::quiet_NaN());

class EmissionGrid {
 public:
  static constexpr double kDefaultStep_s = 1e-3;
  // Covers arrival times [begin_s, end_s] (end inclusive, rounded up to the grid).
  // `recording_delay_s`: the channel records the sound reaching the mic at t at t + delay (a
  // late clock, a slow channel): the grid's times are the recording's.
  EmissionGrid(const Trajectory& trajectory, const Receiver& receiver, bool mirrored,
               double speed_of_sound_mps, double begin_s, double end_s,
               double step_s = kDefaultStep_s, double recording_delay_s = 0.0);
  EmissionGrid(const Trajectory& trajectory, const Eigen::Vector3d& receiver_m, bool mirrored,
               double speed_of_sound_mps, double begin_s, double end_s,
               double step_s = kDefaultStep_s)
      : EmissionGrid(trajectory, Receiver::fixed(receiver_m), mirrored, speed_of_sound_mps, begin_s,
                     end_s, step_s) {}

  double begin_s() const { return begin_s_; }
  double step_s() const { return step_s_; }
  std::size_t intervals() const { return emission_time_s_.size() - 1; }
  double emission_time(double arrival_time_s) const;  // cubic Hermite
  double distance_m(double arrival_time_s) const;     // linear: |p(t_e) - m(t)|
  double min_emission_time() const { return emission_time_s_.front(); }
  double max_emission_time() const { return emission_time_s_.back(); }

  // Adds gain / r(t) * source(t_e(t)) to out[n * stride] for output samples n in
  // [frame_begin, frame_end), at t = n / sample_rate_hz. `source` must cover the emission times
  // (plus the kernel). Callers render in chunks so the output stays in cache across paths.
  void accumulate(const SourceBuffer& source, double gain, double sample_rate_hz,
                  std::size_t frame_begin, std::size_t frame_end, float* out,
                  std::size_t stride) const;

 private:
  double begin_s_;
  double step_s_;
  std::vector<double> emission_time_s_;
  std::vector<double> derivative_;
  std::vector<double> distance_m_;
};

}  // namespace dronetrack::sim
