#include "fusion/track_confirmation.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

#include <Eigen/Cholesky>

#include "fusion/triangulation.hpp"

namespace dronetrack::fusion {

int recent_arrays(const Track& track, std::size_t array_count) {
  int count = 0;
  for (std::size_t a = 0; a < array_count; ++a)
    if (track.last_update_s - track.heard_by_array_s[a] <= kContributionMemoryS) ++count;
  return count;
}

std::uint64_t arrays_fed_since_birth(const Track& track, std::size_t array_count) {
  std::uint64_t fed = 0;
  for (std::size_t a = 0; a < array_count; ++a) {
    const int at_birth = static_cast<int>((track.birth_arrays >> a) & 1u);
    if (track.updates_by_array[a] > at_birth) fed |= std::uint64_t{1} << a;
  }
  return fed;
}

bool held_by_one_array(const Track& track, std::size_t array_count, int confirm_hits) {
  if (track.confirmed || track.one_array) return false;
  const std::uint64_t fed = arrays_fed_since_birth(track, array_count);
  return std::has_single_bit(fed) &&
         track.updates_by_array[static_cast<std::size_t>(std::countr_zero(fed))] >= confirm_hits;
}

namespace {
// The angle at an array between the directions to two points (vectors from its centre), each
// range floored at 1 m.
double angle_between_rad(const Eigen::Vector3d& to_a, const Eigen::Vector3d& to_b) {
  const double cosine = to_a.dot(to_b) / (std::max(to_a.norm(), 1.0) * std::max(to_b.norm(), 1.0));
  return std::acos(std::clamp(cosine, -1.0, 1.0));
}
}  // namespace

TrackConfirmation::TrackConfirmation(const FusionParams& params, double floor_variance_rad2,
                                     double gate_chi2, double speed_of_sound_mps)
    : params_(params),
      floor_variance_rad2_(floor_variance_rad2),
      gate_chi2_(gate_chi2),
      speed_of_sound_mps_(speed_of_sound_mps) {}

bool TrackConfirmation::confirmable(const Track& track, std::span<const Track> tracks,
                                    std::span<const Eigen::Vector3d> centres_m) const {
  const std::uint32_t window_mask =
      params_.confirm_window >= 32 ? ~0u : ((1u << params_.confirm_window) - 1u);
  const int min_arrays =
      std::min<int>(params_.confirm_min_arrays, static_cast<int>(centres_m.size()));
  int arrays_heard = 0;
  int arrays_repeating = 0;  // arrays that updated it at confirm_hits distinct times
  int hits = 0;
  int updates = 0;
  for (std::size_t a = 0; a < centres_m.size(); ++a) {
    updates += track.updates_by_array[a];
    if (track.heard_by_array_s[a] != kNeverS) ++arrays_heard;
    if (track.updates_by_array[a] >= params_.confirm_hits) ++arrays_repeating;
    hits += std::popcount(track.hits_by_array[a] & window_mask);
  }
  // Ghost rejection (confirm_min_arrays): a crossing of two drones' rays is consistent with the
  // two arrays that made it at one moment, rarely with a third. A drone only two arrays can hear
  // (the others masked by a louder drone) gives the same evidence by continuity in time: two
  // rays in 3-D are skew unless they meet at the drone, so a ghost does not keep taking DOAs of
  // both arrays while the drones move. Both arrays must have updated it confirm_hits times.
  // The initiating pair agrees by construction, so two distinct arrays are no evidence: on a
  // two-array site (min_arrays clamped to 2) continuity decides, not the pair's first fix.
  // A one-array track (issue 15) has only continuity: its array updated it confirm_hits times.
  const bool supported = (arrays_heard >= min_arrays && (arrays_heard > 2 || min_arrays <= 1)) ||
                         arrays_repeating >= 2 || (track.one_array && arrays_repeating >= 1);
  // Nor is a track under the ground by more than its own uncertainty: where two drones' rays
  // (or a drone's and its ground image's) cross low, a ghost starts near the ground and sinks.
  const double altitude_m = track.filter->mean()(StateBlock::position + 2);
  const double altitude_std_m = std::sqrt(std::max(
      track.filter->covariance()(StateBlock::position + 2, StateBlock::position + 2), 0.0));
  const bool above_ground = altitude_m + altitude_std_m >= params_.ground_altitude_m;
  // Outlier-born (issue 17): most of its DOAs came in frames whose arrays had none to spare
  // beyond the confirmed tracks they hear. An impulsive outlier takes the place of a confirmed
  // track's DOA; a second source adds a DOA to the frame.
  const bool displacing = 2 * track.crowded_updates > updates;
  // One source, one spectrum: a comb at one array and none at another once each array gave
  // confirm_hits analysed DOAs; combs of spacings Doppler cannot join from the first DOA each
  // (mixed draw 29: at 0.1 s N4's ray to D1, comb 150 Hz, crossed N2's to the car, 100 Hz, and
  // was confirmed at 0.3 s, before N2 gave confirm_hits DOAs).
  const std::span<const AcousticTally> spectra(track.acoustic_by_array.data(), centres_m.size());
  const bool two_sources =
      spectra_disagree(spectra, params_.confirm_hits, params_.init_max_speed_mps,
                       speed_of_sound_mps_) ||
      spectra_disagree(spectra, 1, params_.init_max_speed_mps, speed_of_sound_mps_, false);
  // Nor a track that no second array fed after the moment its rays met: three rays meeting at one
  // moment fixed it, within gates widened for the source's motion between the rays' emission
  // times (at the run's start or at long range, tens of metres), and a source that several arrays
  // hear keeps giving them DOAs there; a crossing of one source's ray with others' does not
  // (issue 14, mixed draw 28: N4's ray to D1 met N2's to the car and N3's to D1, 7 degrees off, at
  // 0.085 s; only N4 fed it after, N3's DOAs went to D1's own track, N2's to the car's; confirmed
  // at 0.235 s on its birth's three arrays and N4's hits, then `drone` for 5.9 s).
  const bool one_array_since_birth =
      !track.one_array && std::popcount(arrays_fed_since_birth(track, centres_m.size())) < 2;
  return supported && above_ground && hits >= params_.confirm_hits && !displacing &&
         !one_array_since_birth && !explained_by_other_tracks(track, tracks, centres_m) &&
         !beneath_another_track(track, tracks) && !two_sources;
}

template <typename Better>
bool TrackConfirmation::along_rays_of(const Track& track, std::span<const Track> tracks,
                                      std::span<const Eigen::Vector3d> centres_m,
                                      const Better& better) const {
  const Eigen::Vector3d position = position_of(track.filter->mean());
  const double spread_m2 = track.filter->covariance().topLeftCorner<3, 3>().trace() / 3.0;
  int supporting = 0;
  for (std::size_t a = 0; a < centres_m.size(); ++a) {
    if (track.last_update_s - track.heard_by_array_s[a] > kContributionMemoryS) continue;
    ++supporting;
    const Eigen::Vector3d to_track = position - centres_m[a];
    const double range_m = std::max(to_track.norm(), 1.0);
    bool explained = false;
    for (const Track& other : tracks) {
      if (&other == &track || !better(other)) continue;
      const Eigen::Vector3d to_other = position_of(other.filter->mean()) - centres_m[a];
      const double other_range_m = std::max(to_other.norm(), 1.0);
      const double other_spread_m2 = other.filter->covariance().topLeftCorner<3, 3>().trace() / 3.0;
      const double angle_rad = angle_between_rad(to_track, to_other);
      const double variance_rad2 = floor_variance_rad2_ + spread_m2 / (range_m * range_m) +
                                   other_spread_m2 / (other_range_m * other_range_m);
      if (angle_rad * angle_rad <= gate_chi2_ * variance_rad2) {
        explained = true;
        break;
      }
    }
    if (!explained) return false;
  }
  return supporting > 0;
}

bool TrackConfirmation::explained_by_other_tracks(
    const Track& track, std::span<const Track> tracks,
    std::span<const Eigen::Vector3d> centres_m) const {
  // Only a track with better standing explains: confirmed, or heard by more arrays (a ghost and
  // the drone whose ray it shares explain each other from that array; the drone also has the
  // arrays the ghost lacks).
  const int support = recent_arrays(track, centres_m.size());
  return along_rays_of(track, tracks, centres_m, [&](const Track& other) {
    return other.confirmed || recent_arrays(other, centres_m.size()) > support;
  });
}

bool TrackConfirmation::along_sharper_tracks(const Track& track, std::span<const Track> tracks,
                                             std::span<const Eigen::Vector3d> centres_m) const {
  // Between confirmed tracks standing is no test (each explains the other from an array they
  // share); the one whose position the DOAs fix better is the one they belong to.
  const double spread_m2 = track.filter->covariance().topLeftCorner<3, 3>().trace();
  return along_rays_of(track, tracks, centres_m, [&](const Track& other) {
    return other.confirmed && other.filter->covariance().topLeftCorner<3, 3>().trace() < spread_m2;
  });
}

bool TrackConfirmation::duplicate_along_ray(const Track& track, std::span<const Track> tracks,
                                            std::span<const Eigen::Vector3d> centres_m) const {
  if (!track.confirmed || recent_arrays(track, centres_m.size()) != 1) return false;
  const double since_s = track.last_update_s - kContributionMemoryS;
  // The one array recent_arrays() counted, by its own test.
  std::size_t feeding = 0;
  while (feeding < centres_m.size() &&
         track.last_update_s - track.heard_by_array_s[feeding] > kContributionMemoryS)
    ++feeding;
  if (feeding == centres_m.size()) return false;
  // Only the spread across the ray moves the direction: a one-array track's spread lies along
  // its ray (its range is open), which widens no angular gate.
  const auto across_variance_rad2 = [&](const Track& of, const Eigen::Vector3d& to_m) {
    const double range_m = std::max(to_m.norm(), 1.0);
    const Eigen::Vector3d along = to_m / range_m;
    const Eigen::Matrix3d spread = of.filter->covariance().topLeftCorner<3, 3>();
    return std::max(spread.trace() - along.dot(spread * along), 0.0) / 2.0 / (range_m * range_m);
  };
  const Eigen::Vector3d to_track = position_of(track.filter->mean()) - centres_m[feeding];
  const double spread_m2 = track.filter->covariance().topLeftCorner<3, 3>().trace();
  for (const Track& other : tracks) {
    if (&other == &track || !other.confirmed ||
        !(other.filter->covariance().topLeftCorner<3, 3>().trace() < spread_m2) ||
        other.heard_by_array_s[feeding] == track.heard_by_array_s[feeding])
      continue;
    bool fed_by_others = false;
    for (std::size_t a = 0; a < centres_m.size(); ++a)
      if (a != feeding && other.heard_by_array_s[a] >= since_s) fed_by_others = true;
    if (!fed_by_others) continue;
    const Eigen::Vector3d to_other = position_of(other.filter->mean()) - centres_m[feeding];
    const double angle_rad = angle_between_rad(to_track, to_other);
    const double variance_rad2 = floor_variance_rad2_ + across_variance_rad2(track, to_track) +
                                 across_variance_rad2(other, to_other);
    if (angle_rad * angle_rad <= gate_chi2_ * variance_rad2) return true;
  }
  return false;
}

bool TrackConfirmation::beneath_another_track(const Track& track,
                                              std::span<const Track> tracks) const {
  const Eigen::Vector3d position = position_of(track.filter->mean());
  const Eigen::Matrix3d covariance = track.filter->covariance().topLeftCorner<3, 3>();
  for (const Track& other : tracks) {
    if (&other == &track || !other.confirmed) continue;
    const Eigen::Vector3d above = position_of(other.filter->mean());
    const double height_m = above.z() - params_.ground_altitude_m;
    if (!(position.z() < above.z()) || !(position.z() - params_.ground_altitude_m > -height_m))
      continue;
    const Eigen::Vector2d offset = (position - above).head<2>();
    const Eigen::Matrix2d spread = covariance.topLeftCorner<2, 2>() +
                                   other.filter->covariance().topLeftCorner<2, 2>() +
                                   Eigen::Matrix2d::Identity();  // 1 m: the echo's own blur
    if (offset.dot(spread.ldlt().solve(offset)) <= chi_square_quantile(0.999, 2)) return true;
  }
  return false;
}

}  // namespace dronetrack::fusion
