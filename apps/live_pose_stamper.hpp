#pragma once
// The live node's side of a moving array (issue 15): poses arrive on the ArrayPose topic while
// DOAs come out of the pipeline stamped with the config's fixed pose. A DOA waits here until two
// poses bracket its time, is then turned to the attitude at that time (doa::restamp) and
// released; one whose pose can no longer come (the stream is past it, a gap, a turn too fast)
// is counted and dropped, never published with a wrong pose. Fixed capacity: no allocation per
// frame once constructed.
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"
#include "doa/pose_sample.hpp"
#include "doa/pose_track.hpp"

namespace dronetrack::apps {

class LivePoseStamper {
 public:
  static constexpr std::size_t kMaxPending = 256;  // ~6 s of DOAs at 20 frames/s x 2 sources

  // max_gap_s: the array's pose_max_gap_s. A DOA waits for its pose until the stream is this
  // much (plus kWaitMargin_s) past its time.
  LivePoseStamper(const doa::ArrayGeometry& geometry, double max_gap_s);

  // A pose on the node's stream clock. False (counted in refused_poses()) when non-finite or
  // not after the newest.
  bool add_pose(const doa::PoseSample& pose);
  // Takes this step's DOAs (stamped with the fixed pose, as NodePipeline gives them); clears
  // `doas`. A full queue drops (and counts) its oldest.
  void add_doas(std::vector<doa::DoaMeasurement>& doas);
  // Appends to `ready`, in order, every waiting DOA whose pose has arrived; drops those whose
  // pose cannot come any more. `now_s`: the node's stream time (the last sample read).
  void release(double now_s, std::vector<doa::DoaMeasurement>& ready);

  std::int64_t dropped() const { return dropped_; }  // DOAs without a pose at their time
  std::int64_t refused_poses() const { return ring_.refused(); }
  std::size_t pending() const { return pending_.size(); }

  static constexpr double kWaitMargin_s = 0.5;  // pose stream latency allowed beyond the gap

 private:
  doa::PoseRing ring_;
  Eigen::Vector3d mic_centroid_m_;
  double max_wait_s_;
  std::vector<doa::DoaMeasurement> pending_;  // time order of arrival; capacity kMaxPending
  std::int64_t dropped_ = 0;
};

}  // namespace dronetrack::apps
