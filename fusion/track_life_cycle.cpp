// Track life cycle: confirmation (the rules: track_confirmation.hpp), the classifier's
// kinematics, coasting and deletion (a spread along the ray of the one array still hearing a
// track is an open range, not a lost track: lost()).
#include <algorithm>
#include <bit>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "fusion/fusion_engine_impl.hpp"

namespace dronetrack::fusion {

namespace {
constexpr double kDuplicateDwellS = 1.0;
}  // namespace

void FusionEngine::Impl::confirm_tracks(double now_s) {
  for (Track& track : tracks) {
    if (track.confirmed || !confirmation->confirmable(track, tracks, last_centre_m)) continue;
    track.confirmed = true;
    track.confirmed_at_s = now_s;
    ++counters.tracks_confirmed;
  }
}

void FusionEngine::Impl::mark_duplicates(double now_s) {
  for (Track& track : tracks) {
    if (!confirmation->duplicate_along_ray(track, tracks, last_centre_m))
      track.duplicate_since_s = kNeverS;
    else if (track.duplicate_since_s == kNeverS)
      track.duplicate_since_s = now_s;
  }
}

void FusionEngine::Impl::life_cycle(double now_s) {
  for (Track& track : tracks) {
    const StateVector& mean = track.filter->mean();
    const double altitude_std_m = std::sqrt(std::max(
        track.filter->covariance()(StateBlock::position + 2, StateBlock::position + 2), 0.0));
    classifier->add_kinematics(track.evidence, position_of(mean), velocity_of(mean), altitude_std_m,
                               track.time_s);
    classifier->classify(track.evidence,
                         confirmation->along_sharper_tracks(track, tracks, last_centre_m));
  }
  delete_expired(now_s);
}

void FusionEngine::Impl::delete_expired(double now_s) {
  const double max_variance = params.max_position_std_m * params.max_position_std_m;
  const auto dead = [&](const Track& track) {
    const bool unconfirmed_expired =
        !track.confirmed && now_s - track.last_update_s > params.tentative_timeout_s;
    if (unconfirmed_expired) ++counters.ghosts_rejected;
    // A real source one array alone hears may cross another track's ray from it; a duplicate
    // stays on that ray, held there by that array's DOAs of the sharper track's source.
    if (track.confirmed && track.duplicate_since_s != kNeverS &&
        now_s - track.duplicate_since_s >= kDuplicateDwellS) {
      ++counters.duplicates_pruned;
      return true;
    }
    const Eigen::Vector3d variance =
        track.filter->covariance().diagonal().segment<3>(StateBlock::position);
    if (!variance.allFinite()) return true;
    // A one-array track's spread along its bearing is what it knows, not a lost track; it ends
    // by timeout.
    if (!track.one_array && !(variance.maxCoeff() <= max_variance) && lost(track, now_s))
      return true;
    const double unheard = now_s - track.last_update_s;
    return unheard > (track.confirmed ? params.coast_timeout_s : params.tentative_timeout_s);
  };
  const auto before = tracks.size();
  tracks.erase(std::remove_if(tracks.begin(), tracks.end(), dead), tracks.end());
  counters.tracks_deleted += static_cast<std::int64_t>(before - tracks.size());
}

int FusionEngine::Impl::last_array(const Track& track) const {
  int last = -1;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    if (track.heard_by_array_s[a] == kNeverS) continue;
    if (last < 0 || track.heard_by_array_s[a] > track.heard_by_array_s[last])
      last = static_cast<int>(a);
  }
  return last;
}

bool FusionEngine::Impl::lost(const Track& track, double now_s) const {
  // Only a range that two arrays did fix (each updated it confirm_hits times) is held open: a
  // track a pair started and no second array kept agreeing with (an outlier's) has none to hold.
  int fixing_arrays = 0;
  for (std::size_t a = 0; a < arrays.size(); ++a)
    if (track.updates_by_array[a] >= params.confirm_hits) ++fixing_arrays;
  if (fixing_arrays < 2) return true;
  // "Still hears it": that array updated it in confirm_hits of its last confirm_window frames (a
  // track that outliers of one array now and then keep alive does not qualify).
  const int last = last_array(track);
  const std::uint32_t window_mask =
      params.confirm_window >= 32 ? ~0u : ((1u << params.confirm_window) - 1u);
  if (last < 0 || now_s - track.heard_by_array_s[last] > kContributionMemoryS ||
      std::popcount(track.hits_by_array[static_cast<std::size_t>(last)] & window_mask) <
          params.confirm_hits)
    return true;
  const Eigen::Vector3d to_track =
      position_of(track.filter->mean()) - last_centre_m[static_cast<std::size_t>(last)];
  const double range_m = to_track.norm();
  if (!(range_m > 1.0)) return true;
  const Eigen::Vector3d along = to_track / range_m;
  const Eigen::Matrix3d spread = track.filter->covariance().topLeftCorner<3, 3>();
  const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - along * along.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(across * spread * across,
                                                              Eigen::EigenvaluesOnly);
  const double max_variance = params.max_position_std_m * params.max_position_std_m;
  return !(solver.eigenvalues().maxCoeff() <= max_variance) ||
         !(9.0 * along.dot(spread * along) < range_m * range_m);
}

}  // namespace dronetrack::fusion
