// The confirmation rules on their own, on tracks placed at known positions.
#include "fusion/track_confirmation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace dronetrack::fusion::track_confirmation_test {
namespace {

Track track_at(const Eigen::Vector3d& position_m, double position_std_m, bool confirmed) {
  Track track;
  track.filter = make_track_filter(FilterKind::ukf, FilterSettings{});
  StateVector mean = StateVector::Zero();
  mean.segment<3>(StateBlock::position) = position_m;
  StateCovariance covariance = StateCovariance::Identity();
  covariance.topLeftCorner<3, 3>() *= position_std_m * position_std_m;
  track.filter->initialise(mean, covariance);
  track.confirmed = confirmed;
  track.heard_by_array_s.fill(kNeverS);
  return track;
}

// Echo: DOAs mixing a source with its ground image meet on the vertical line below it.
TEST(TrackConfirmation, ATrackUnderAConfirmedOneIsItsEcho) {
  FusionParams params;
  params.ground_altitude_m = 0.0;
  const TrackConfirmation rules(params, 1e-6, 13.8, 343.0);
  std::vector<Track> tracks;
  tracks.push_back(track_at({100, 50, 40}, 0.5, true));
  tracks.push_back(track_at({100.5, 50, 12}, 0.5, false));  // below it
  tracks.push_back(track_at({130, 50, 12}, 0.5, false));    // 30 m aside
  tracks.push_back(track_at({100, 50, 60}, 0.5, false));    // above it
  EXPECT_TRUE(rules.beneath_another_track(tracks[1], tracks));
  EXPECT_FALSE(rules.beneath_another_track(tracks[2], tracks));
  EXPECT_FALSE(rules.beneath_another_track(tracks[3], tracks));
  tracks[0].confirmed = false;  // only a confirmed track has echoes
  EXPECT_FALSE(rules.beneath_another_track(tracks[1], tracks));
}

// Ghost: a tentative track on the rays, from both arrays hearing it, of a confirmed track.
TEST(TrackConfirmation, ATrackAlongAConfirmedTracksRaysIsExplained) {
  const FusionParams params;
  const TrackConfirmation rules(params, 1e-6, 13.8, 343.0);
  const std::vector<Eigen::Vector3d> centres{{0, 0, 2}, {100, 0, 2}};
  std::vector<Track> tracks;
  tracks.push_back(track_at({50, 60, 30}, 0.5, true));
  // On array 0's ray to the confirmed track, 1.5 times as far.
  const Eigen::Vector3d on_ray = centres[0] + 1.5 * (Eigen::Vector3d(50, 60, 30) - centres[0]);
  tracks.push_back(track_at(on_ray, 0.5, false));
  Track& ghost = tracks[1];
  ghost.last_update_s = 10.0;
  ghost.heard_by_array_s[0] = 10.0;
  EXPECT_TRUE(rules.explained_by_other_tracks(ghost, tracks, centres));
  // Array 1 also hears it, and from there it is off the confirmed track's ray.
  ghost.heard_by_array_s[1] = 10.0;
  EXPECT_FALSE(rules.explained_by_other_tracks(ghost, tracks, centres));
}

// Ghost of two drones (mixed site draw 24): array 0's ray to one confirmed drone crosses array 1's
// ray to the other. The track at the crossing, known worse than either, lies along better-fixed
// tracks' rays from both arrays that hear it; a third array that hears it there is its own.
TEST(TrackConfirmation, ACrossingOfTwoSharperTracksRaysIsAlongThem) {
  const FusionParams params;
  const TrackConfirmation rules(params, 1e-6, 13.8, 343.0);
  const std::vector<Eigen::Vector3d> centres{{0, 0, 2}, {100, 0, 2}, {50, -100, 2}};
  const Eigen::Vector3d crossing(50, 60, 30);
  // Heard by arrays 0 and 1 within the last second.
  const auto ghost_at = [&](double position_std_m) {
    Track ghost = track_at(crossing, position_std_m, true);
    ghost.last_update_s = 10.0;
    ghost.heard_by_array_s[0] = 10.0;
    ghost.heard_by_array_s[1] = 9.5;
    return ghost;
  };
  std::vector<Track> tracks;
  tracks.push_back(track_at(centres[0] + 1.4 * (crossing - centres[0]), 0.5, true));
  tracks.push_back(track_at(centres[1] + 0.7 * (crossing - centres[1]), 0.5, true));
  tracks.push_back(ghost_at(2.0));
  EXPECT_TRUE(rules.along_sharper_tracks(tracks[2], tracks, centres));
  // The drones are not along the ghost's rays: it is fixed worse than they are.
  tracks[0].last_update_s = 10.0;
  tracks[0].heard_by_array_s[0] = 10.0;
  EXPECT_FALSE(rules.along_sharper_tracks(tracks[0], tracks, centres));
  // Fixed better than the tracks whose rays it shares: its DOAs are its own.
  tracks[2] = ghost_at(0.3);
  EXPECT_FALSE(rules.along_sharper_tracks(tracks[2], tracks, centres));
  tracks[2] = ghost_at(2.0);
  // A tentative track explains nothing.
  tracks[1].confirmed = false;
  EXPECT_FALSE(rules.along_sharper_tracks(tracks[2], tracks, centres));
  tracks[1].confirmed = true;
  // A third array hears it, 6 degrees off both drones' directions from there.
  tracks[2].heard_by_array_s[2] = 10.0;
  EXPECT_FALSE(rules.along_sharper_tracks(tracks[2], tracks, centres));
  // Heard by no array within the last second: nothing supports it, nothing to explain.
  tracks[2].last_update_s = 20.0;
  EXPECT_FALSE(rules.along_sharper_tracks(tracks[2], tracks, centres));
}

// Mixed site draw 28 at 0.085 s: N4's ray to a drone met N2's ray to a passing car and N3's ray
// to the drone (7 degrees off, within the gate widened for the motion between the emission
// times) at 22 m up, 40 m short of the drone. Only N4 fed the track after that moment; N3's
// DOAs went to the drone's own track, N2's to the car's. Three arrays at one moment and one
// array's continuity do not confirm it; a second array feeding it after that moment does.
TEST(TrackConfirmation, ATrackOnlyOneArrayFedSinceItsBirthIsNotConfirmed) {
  FusionParams params;
  params.ground_altitude_m = 0.0;
  const TrackConfirmation rules(params, 1e-6, 13.8, 343.0);
  const std::vector<Eigen::Vector3d> centres{
      {-100, -100, 2}, {100, -100, 2}, {100, 100, 2}, {-100, 100, 2}};
  constexpr std::size_t n2 = 1;
  constexpr std::size_t n3 = 2;
  constexpr std::size_t n4 = 3;
  std::vector<Track> tracks;
  tracks.push_back(track_at({-257, 131, 0.5}, 3.0, true));  // the car, N2 and N3
  tracks.push_back(track_at({-152, 8, 36}, 2.0, false));    // the drone's own, N3 and N4
  tracks.push_back(track_at({-130.6, 45.8, 21.9}, 2.0, false));
  Track& crossing = tracks[2];
  const auto feed = [&](std::size_t array, double time_s) {
    crossing.hits_by_array[array] = (crossing.hits_by_array[array] << 1) | 1u;
    ++crossing.updates_by_array[array];
    crossing.heard_by_array_s[array] = time_s;
    crossing.last_update_s = std::max(crossing.last_update_s, time_s);
  };
  for (const std::size_t array : {n4, n2, n3}) {
    feed(array, 0.085);
    crossing.birth_arrays |= std::uint64_t{1} << array;
  }
  for (int frame = 1; frame <= 4; ++frame) feed(n4, 0.085 + 0.05 * frame);
  EXPECT_FALSE(rules.confirmable(crossing, tracks, centres));
  // N3 feeds it after its birth too: two arrays agree beyond one moment.
  feed(n3, 0.285);
  EXPECT_TRUE(rules.confirmable(crossing, tracks, centres));
}

TEST(TrackConfirmation, HeldByOneArrayOnlyWhileNoSecondArrayUpdatedIt) {
  Track track = track_at({0, 50, 20}, 1.0, false);
  track.birth_arrays = 0b011;  // its birth pair, arrays 0 and 1
  track.updates_by_array[0] = 5;
  track.updates_by_array[1] = 1;
  EXPECT_TRUE(held_by_one_array(track, 3, 5));
  track.updates_by_array[0] = 4;  // array 0 not yet confirm_hits times
  EXPECT_FALSE(held_by_one_array(track, 3, 5));
  track.updates_by_array[0] = 5;
  track.updates_by_array[1] = 2;  // its birth partner fed it again
  EXPECT_FALSE(held_by_one_array(track, 3, 5));
  track.updates_by_array[1] = 1;
  // One DOA of an array that was not at its birth is a second array after its birth, as for
  // confirmation (the rule once counted only arrays with two updates).
  track.updates_by_array[2] = 1;
  EXPECT_FALSE(held_by_one_array(track, 3, 5));
  track.updates_by_array[2] = 0;
  track.confirmed = true;
  EXPECT_FALSE(held_by_one_array(track, 3, 5));
}

doa::AcousticFeatures comb(double fundamental_hz) {
  doa::AcousticFeatures features;
  features.valid = true;
  features.fundamental_hz = fundamental_hz;
  return features;
}

// One source, one spectrum: a comb at one array and none at another, or spacings further apart
// than the Doppler shift allows (2 v / c + 5 %: 2 * 30 / 343 + 0.05 = 22.5 %), are two sources.
TEST(SpectrumAgreement, TwoArraysHearingDifferentSpectraDisagree) {
  std::vector<AcousticTally> tallies(2);
  for (int k = 0; k < 8; ++k) tallies[0].add(comb(120.0));
  for (int k = 0; k < 8; ++k) tallies[1].add(comb(140.0));  // +16.7 %: Doppler explains it
  EXPECT_FALSE(spectra_disagree(tallies, 5, 30.0, 343.0));
  tallies[1] = {};
  for (int k = 0; k < 8; ++k) tallies[1].add(comb(160.0));  // +33 %
  EXPECT_TRUE(spectra_disagree(tallies, 5, 30.0, 343.0));
  tallies[1] = {};
  for (int k = 0; k < 8; ++k) tallies[1].add(comb(0.0));  // analysed, no comb
  EXPECT_TRUE(spectra_disagree(tallies, 5, 30.0, 343.0));
  // Too few analysed DOAs at the second array to say anything.
  EXPECT_FALSE(spectra_disagree(tallies, 10, 30.0, 343.0));
  // From one analysed DOA each: two combs Doppler cannot join (150 and 100 Hz: mixed draw 29's
  // birth crossing) are two sources; 150 and 160 Hz (+6.7 %) may be one; a comb and no comb from
  // one DOA each say nothing (a drone's comb is missed in some analyses).
  std::vector<AcousticTally> first(2);
  first[0].add(comb(150.0));
  first[1].add(comb(100.0));
  EXPECT_TRUE(spectra_disagree(first, 1, 25.0, 343.0, false));
  EXPECT_FALSE(spectra_disagree(first, 5, 25.0, 343.0, false));
  first[1] = {};
  first[1].add(comb(160.0));
  EXPECT_FALSE(spectra_disagree(first, 1, 25.0, 343.0, false));
  first[1] = {};
  first[1].add(comb(0.0));
  EXPECT_FALSE(spectra_disagree(first, 1, 25.0, 343.0, false));
  EXPECT_TRUE(spectra_disagree(first, 1, 25.0, 343.0, true));
  // Features the node could not compute are no vote.
  AcousticTally none;
  none.add(doa::AcousticFeatures{});
  EXPECT_EQ(none.analysed, 0);
}

// A sharper confirmed track on a source 60 m out that array 1 fed at 10 s, and three arrays.
struct SharpSource {
  TrackConfirmation rules{FusionParams{}, 1e-6, 13.8, 343.0};
  std::vector<Eigen::Vector3d> centres{{0, 0, 2}, {100, 0, 2}, {50, -100, 2}};
  Eigen::Vector3d source{50, 60, 30};
  std::vector<Track> tracks;
  SharpSource() {
    tracks.push_back(track_at(source, 0.5, true));
    tracks[0].last_update_s = 10.0;
    tracks[0].heard_by_array_s[1] = 10.0;
  }
  // A confirmed track array 0 alone fed at 10 s, `along_std_m` along array 0's ray and 0.3 m
  // across it, `angle_deg` off its ray to the source.
  Track one_array_track(double angle_deg, double along_std_m) const {
    const Eigen::Vector3d ray = (source - centres[0]).normalized();
    const Eigen::Vector3d across = ray.cross(Eigen::Vector3d::UnitZ()).normalized();
    const double angle_rad = angle_deg * 3.14159265358979 / 180.0;
    const Eigen::Vector3d direction = std::cos(angle_rad) * ray + std::sin(angle_rad) * across;
    Track track = track_at(centres[0] + 120.0 * direction, 0.3, true);
    StateCovariance covariance = track.filter->covariance();
    covariance.topLeftCorner<3, 3>() +=
        along_std_m * along_std_m * direction * direction.transpose();
    track.filter->initialise(track.filter->mean(), covariance);
    track.last_update_s = 10.0;
    track.heard_by_array_s[0] = 10.0;
    return track;
  }
};

// Duplicate along a ray (issue 14 item 6, mixed draw 33): a confirmed track array 0 alone fed in
// the last second, on array 0's ray to a sharper confirmed track that arrays 1 and 2 feed: array
// 0 hears one source there, which the sharper track already places.
TEST(TrackConfirmation, AOneArrayTrackOnASharperTracksRayIsADuplicate) {
  SharpSource site;
  std::vector<Track>& tracks = site.tracks;
  tracks[0].heard_by_array_s[2] = 9.8;
  tracks.push_back(site.one_array_track(0.0, 5.0));
  Track& duplicate = tracks[1];
  duplicate.heard_by_array_s[1] = 8.5;  // before the last second
  const auto is_duplicate = [&] {
    return site.rules.duplicate_along_ray(duplicate, tracks, site.centres);
  };
  EXPECT_TRUE(is_duplicate());
  EXPECT_FALSE(site.rules.duplicate_along_ray(tracks[0], tracks, site.centres));
  // Array 0's latest frame gave each a DOA: it hears two sources along that ray.
  tracks[0].heard_by_array_s[0] = 10.0;
  EXPECT_FALSE(is_duplicate());
  // Its frames' one DOA went now to one, now to the other: one source.
  tracks[0].heard_by_array_s[0] = 9.95;
  EXPECT_TRUE(is_duplicate());
  tracks[0].heard_by_array_s[0] = kNeverS;
  // A second array fed it in the last second: that array places it elsewhere.
  duplicate.heard_by_array_s[1] = 9.5;
  EXPECT_FALSE(is_duplicate());
  duplicate.heard_by_array_s[1] = 8.5;
  // Nor when no other array fed the sharper track in the last second.
  tracks[0].heard_by_array_s[1] = 8.0;
  tracks[0].heard_by_array_s[2] = 8.0;
  EXPECT_FALSE(is_duplicate());
  tracks[0].heard_by_array_s[1] = 10.0;
  // Nor along a track that is not confirmed.
  tracks[0].confirmed = false;
  EXPECT_FALSE(is_duplicate());
  tracks[0].confirmed = true;
  EXPECT_TRUE(is_duplicate());
}

// A track one array alone hears has its spread along that array's ray (its range is open): that
// spread does not widen the angle within which it is taken for another track's duplicate. 30 m
// std along the ray: 3 degrees off the sharper track's ray it is a second source, on it a
// duplicate.
TEST(TrackConfirmation, AOneArrayTrackBesideASharperTracksRayIsKept) {
  SharpSource site;
  site.tracks.push_back(site.one_array_track(3.0, 30.0));
  EXPECT_FALSE(site.rules.duplicate_along_ray(site.tracks[1], site.tracks, site.centres));
  site.tracks[1] = site.one_array_track(0.0, 30.0);
  EXPECT_TRUE(site.rules.duplicate_along_ray(site.tracks[1], site.tracks, site.centres));
}

}  // namespace
}  // namespace dronetrack::fusion::track_confirmation_test
