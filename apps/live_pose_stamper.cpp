#include "apps/live_pose_stamper.hpp"

#include <optional>

namespace dronetrack::apps {

LivePoseStamper::LivePoseStamper(const doa::ArrayGeometry& geometry, double max_gap_s)
    : ring_(max_gap_s),
      mic_centroid_m_(doa::mic_centroid_m(geometry)),
      max_wait_s_(max_gap_s + kWaitMargin_s) {
  pending_.reserve(kMaxPending);
}

bool LivePoseStamper::add_pose(const doa::PoseSample& pose) { return ring_.push(pose); }

void LivePoseStamper::add_doas(std::vector<doa::DoaMeasurement>& doas) {
  for (doa::DoaMeasurement& doa : doas) {
    if (pending_.size() == kMaxPending) {
      pending_.erase(pending_.begin());
      ++dropped_;
    }
    pending_.push_back(std::move(doa));
  }
  doas.clear();
}

void LivePoseStamper::release(double now_s, std::vector<doa::DoaMeasurement>& ready) {
  auto kept = pending_.begin();
  for (auto doa = pending_.begin(); doa != pending_.end(); ++doa) {
    const std::optional<doa::PoseStamp> stamp = ring_.stamp(doa->time_s, mic_centroid_m_);
    if (stamp) {
      // The pipeline solved it in the frame of the fixed pose it stamped.
      const Eigen::Matrix3d solved = doa->pose.array_to_site.toRotationMatrix();
      doa::restamp(*doa, *stamp, solved);
      ready.push_back(std::move(*doa));
    } else if (doa->time_s > ring_.newest_s() && now_s - doa->time_s < max_wait_s_) {
      if (kept != doa) *kept = std::move(*doa);  // its pose may still come
      ++kept;
    } else {
      ++dropped_;
    }
  }
  pending_.erase(kept, pending_.end());
}

}  // namespace dronetrack::apps
