#pragma once
// Where a moving array was at any time of its recording (issue 15): a time-ordered list of
// PoseSample lines, interpolated linearly in position and by quaternion slerp in attitude (so a
// heading that crosses +-180 deg turns the short way). PoseRing is the live counterpart, a
// bounded ring of the latest samples from the ArrayPose stream. Both give the PoseStamp a DOA
// carries; the fixed stamp of an array that does not move comes from its geometry alone.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"
#include "doa/pose_sample.hpp"

namespace dronetrack::doa {

// Between two pose lines the heading may change this much at most: beyond it the platform may
// have turned either way, or several times, and interpolating would invent an attitude.
inline constexpr double kMaxPoseYawStep_deg = 45.0;

// The config's pose of an array that does not move (moving = false).
PoseStamp fixed_stamp(const ArrayGeometry& geometry);

// Rz(yaw) Ry(pitch) Rx(roll) of one pose line.
Eigen::Quaterniond pose_attitude(const PoseSample& sample);

// The pose at `time_s` between `before` and `after` (before.time_s <= time_s <= after.time_s):
// position linear, attitude slerp; the acoustic centre is the mic centroid carried by it.
PoseStamp interpolate_pose(const PoseSample& before, const PoseSample& after, double time_s,
                           const Eigen::Vector3d& mic_centroid_array_m);

// The mic centroid in the array frame (the point DOAs point from), m.
Eigen::Vector3d mic_centroid_m(const ArrayGeometry& geometry);

class PoseTrack {
 public:
  PoseTrack() = default;
  // Throws std::invalid_argument unless there are >= 2 samples with finite values and strictly
  // increasing times (the config reader names file:line first; this guards other callers).
  explicit PoseTrack(std::vector<PoseSample> samples);

  bool empty() const { return samples_.empty(); }
  double start_s() const { return samples_.empty() ? 0.0 : samples_.front().time_s; }
  double end_s() const { return samples_.empty() ? 0.0 : samples_.back().time_s; }
  bool covers(double time_s) const {
    return !samples_.empty() && time_s >= start_s() && time_s <= end_s();
  }
  const std::vector<PoseSample>& samples() const { return samples_; }

  // The pose of `geometry`'s mics at `time_s` (moving = true); nullopt outside the span.
  // No allocation: a binary search and one slerp.
  std::optional<PoseStamp> stamp(double time_s, const ArrayGeometry& geometry) const;
  // The origin's velocity between the lines around `time_s`, site frame; nullopt outside the span.
  std::optional<Eigen::Vector3d> velocity_mps(double time_s) const;

 private:
  // The index of the line after `time_s` (time_s inside the span).
  std::size_t after(double time_s) const;
  std::vector<PoseSample> samples_;
};

// The latest poses of one array as they arrive live (time-ordered; a sample not after the
// newest is refused and counted). Fixed capacity: push() and stamp() never allocate. Not
// thread-safe: one thread feeds it and stamps with it.
class PoseRing {
 public:
  static constexpr std::size_t kCapacity = 512;  // 51 s at 10 Hz, 5 s at 100 Hz

  // max_gap_s: two consecutive samples further apart than this do not cover the time between.
  explicit PoseRing(double max_gap_s = 1.0) : max_gap_s_(max_gap_s) {}

  // False (and counted in refused()) for a non-finite sample or one not after the newest.
  bool push(const PoseSample& sample);
  // nullopt when no two consecutive samples bracket `time_s` (not yet arrived, too old, across
  // a gap or a turn of more than kMaxPoseYawStep_deg).
  std::optional<PoseStamp> stamp(double time_s, const Eigen::Vector3d& mic_centroid_array_m) const;
  std::size_t size() const { return count_; }
  // The newest sample's time (-inf when empty).
  double newest_s() const;
  std::int64_t refused() const { return refused_; }

 private:
  const PoseSample& at(std::size_t index) const {  // 0 = oldest
    return samples_[(first_ + index) % kCapacity];
  }
  std::array<PoseSample, kCapacity> samples_{};
  std::size_t first_ = 0;
  std::size_t count_ = 0;
  double max_gap_s_;
  std::int64_t refused_ = 0;
};

// Moves a DOA solved in the frame of `solved_array_to_site` (the solver's fixed rotation) to
// the attitude of `stamp` and attaches the stamp: direction, its (azimuth, elevation)
// covariance and the ambiguity axis turn by stamp.array_to_site * solved^T. The one place a
// DOA's site-frame vectors follow the array's attitude at the frame's time. A mirror pair keeps
// reporting the image above the array plane.
void restamp(DoaMeasurement& measurement, const PoseStamp& stamp,
             const Eigen::Matrix3d& solved_array_to_site);

}  // namespace dronetrack::doa
