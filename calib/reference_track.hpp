#pragma once
// The calibration source's known path: positions on the reference clock (a GPS logger on the
// drone, or a loudspeaker at surveyed points), linearly interpolated between samples, and the
// emission time of the sound an array hears at a given arrival time.
#include <optional>
#include <vector>

#include <Eigen/Core>

namespace dronetrack::calib {

struct ReferenceSample {
  double time_s = 0.0;  // reference clock (the recordings' nominal clock)
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  // site frame
};

// Where a time falls between two samples: position = (1 - weight) * P[index] + weight * P[index+1].
struct ReferenceBracket {
  int index = 0;
  double weight = 0.0;
};

class ReferenceTrack {
 public:
  // `samples` sorted by strictly increasing time (checked by the reader; std::invalid_argument
  // here otherwise). Two consecutive samples further apart than `max_gap_s` leave a gap no time
  // is interpolated across.
  ReferenceTrack(std::vector<ReferenceSample> samples, double max_gap_s);

  const std::vector<ReferenceSample>& samples() const { return samples_; }
  double start_s() const { return samples_.front().time_s; }
  double end_s() const { return samples_.back().time_s; }

  // The bracket of `time_s`; nullopt outside the track or inside a gap.
  std::optional<ReferenceBracket> bracket(double time_s) const;
  // Interpolated position along `positions` (one per sample: the GPS fixes or their current
  // estimates).
  Eigen::Vector3d position_at(const ReferenceBracket& bracket,
                              const std::vector<Eigen::Vector3d>& positions) const;

  // The source's velocity at `time_s`: the slope of a straight-line fit to the logged fixes
  // within +-half_window_s (a difference of two noisy fixes 0.1 s apart would be metres per
  // second off). Zero when fewer than 2 fixes fall in the window.
  Eigen::Vector3d velocity_mps(double time_s, double half_window_s) const;

  // The time t_e the sound left the source so that it reaches `listener_m` at `arrival_s` (both
  // on the reference clock): t_e + |p(t_e) - listener| / c = arrival_s. Fixed-point iteration
  // (a contraction while the source is slower than sound). nullopt when t_e is off the track.
  std::optional<double> emission_time_s(double arrival_s, const Eigen::Vector3d& listener_m,
                                        double speed_of_sound_mps,
                                        const std::vector<Eigen::Vector3d>& positions) const;

 private:
  std::vector<ReferenceSample> samples_;
  double max_gap_s_;
};

}  // namespace dronetrack::calib
