#pragma once
// Track confirmation (SPEC 4.6 M-of-N, plus the ghost, echo and outlier rules of issues 14 and
// 17): whether a tentative track may be confirmed, judged against the other tracks. Pure reads
// of the tracker's records; the engine marks and counts.
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "fusion/fusion_params.hpp"
#include "fusion/track_record.hpp"

namespace dronetrack::fusion {

// Arrays that updated the track within kContributionMemoryS of its last update.
int recent_arrays(const Track& track, std::size_t array_count);

// The arrays (bit a: array a) that updated the track after the DOAs it was born from
// (Track::birth_arrays).
std::uint64_t arrays_fed_since_birth(const Track& track, std::size_t array_count);

// A tentative track (not a one-array track) that one array has updated confirm_hits times while
// no other array updated it after its birth: nothing but its first pair ever said where along
// that array's ray it is. Where the pair was one source's ray crossing another's (issue 14: a
// drone's ray and a passing car's), it would otherwise hold that array's DOAs of the drone for as
// long as they come and keep the drone's own pair from starting its track.
bool held_by_one_array(const Track& track, std::size_t array_count, int confirm_hits);

class TrackConfirmation {
 public:
  // floor_variance_rad2: the DOA noise floor; gate_chi2: the 2-dof gate; speed_of_sound_mps:
  // the site's.
  TrackConfirmation(const FusionParams& params, double floor_variance_rad2, double gate_chi2,
                    double speed_of_sound_mps);

  // Every rule below passes: M of N hits, enough arrays (or continuity), a second array feeding
  // it after its birth, above the ground, not outlier-born, no ghost, no echo, one spectrum.
  // centres_m: each array's centre at its newest frame (site order); tracks: every live track
  // (`track` among them).
  bool confirmable(const Track& track, std::span<const Track> tracks,
                   std::span<const Eigen::Vector3d> centres_m) const;

  // Ghost test (issue 14): from every array that supports it, the track lies along the ray of
  // another track with better standing, so that track already explains its DOAs (two drones'
  // crossing rays).
  bool explained_by_other_tracks(const Track& track, std::span<const Track> tracks,
                                 std::span<const Eigen::Vector3d> centres_m) const;
  // Echo test (issue 14): every array's rays to a source and to its ground mirror lie in the
  // vertical plane through both, so DOAs that mix the two (an echo the node could not remove)
  // meet on the vertical line through the source, below it. A track there, under a confirmed
  // track, is that mixture.
  bool beneath_another_track(const Track& track, std::span<const Track> tracks) const;
  // The same test for a track of any standing against the confirmed tracks whose positions are
  // known better than its own: its DOAs are theirs, so what they sound like says nothing of it
  // (the classifier does not make it a drone on them).
  bool along_sharper_tracks(const Track& track, std::span<const Track> tracks,
                            std::span<const Eigen::Vector3d> centres_m) const;
  // Duplicate test (issue 14 item 6): one array alone fed the confirmed `track` in the last
  // kContributionMemoryS, and from that array it lies along the ray of a confirmed track with a
  // smaller position spread that other arrays feed, and to which that array's latest frame gave
  // no DOA of its own: the array hears one source there (each frame's DOA goes to one of the two;
  // two sources it resolves give both a DOA in one frame), and cannot tell where along its ray:
  // `track` says nothing the sharper track does not, and holds that array's DOAs from it.
  bool duplicate_along_ray(const Track& track, std::span<const Track> tracks,
                           std::span<const Eigen::Vector3d> centres_m) const;

 private:
  // From every array that recently updated `track`, it lies within the gate of the direction to
  // some track `better` accepts.
  template <typename Better>
  bool along_rays_of(const Track& track, std::span<const Track> tracks,
                     std::span<const Eigen::Vector3d> centres_m, const Better& better) const;

  FusionParams params_;
  double floor_variance_rad2_;
  double gate_chi2_;
  double speed_of_sound_mps_;
};

}  // namespace dronetrack::fusion
