// Track birth: a DOA no track took seeds a track once its moment's DOAs are in (initiate_pending):
// paired with another array's ray by triangulation, preferring the point more arrays agree with
// (issue 14's ghosts), or, with single_array_start, from its array alone (issue 15).
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "fusion/bearing_prior.hpp"
#include "fusion/fusion_engine_impl.hpp"

namespace dronetrack::fusion {

void FusionEngine::Impl::initiate_pending() {
  // The seeds due by `due_s` whose DOA no track took nor started since go to `start`; the others
  // wait.
  const auto start_due = [this](std::vector<PendingSeed>& seeds, double due_s,
                                bool (Impl::*start)(int, std::size_t, double)) {
    std::size_t kept = 0;
    for (const PendingSeed& seed : seeds) {
      if (seed.time_s > due_s) {
        seeds[kept++] = seed;
        continue;
      }
      const auto index = recent[seed.array].find(seed.sequence);
      if (!index) continue;
      const RecentDoa& doa = recent[seed.array][*index];
      if (!doa.associated && !doa.used) (this->*start)(seed.array, *index, seed.time_s);
    }
    seeds.resize(kept);
  };
  // Two arrays: no third to vote, nothing to wait for.
  const double delay_s = arrays.size() > 2 ? kInitiationDelayS : 0.0;
  start_due(pending_seeds, fed_time_s - delay_s, &Impl::try_initiate);
  // Only once no second array could still pair it: the window the pairing looks across.
  start_due(pending_single_seeds, fed_time_s - params.init_pair_window_s,
            &Impl::try_start_one_array);
}

bool FusionEngine::Impl::try_initiate(int array, std::size_t recent_index, double time_s) {
  if (tracks.size() >= static_cast<std::size_t>(params.max_tracks)) return false;
  RecentDoa& seed = recent[array][recent_index];
  const auto array_count = static_cast<int>(arrays.size());
  // Rays of different arrays at nearby reception times left the drone at different emission
  // times (t - r / c); it moves up to init_max_speed_mps in between. Widen each ray's angular
  // noise by that motion seen from its range, relative to the seed's emission time.
  // A cone's 1-D residual leaves its pad slot at 0 (state.hpp): the same formula serves both.
  const auto chi2_against = [&](const RecentDoa& doa, int /*doa_array*/,
                                const Eigen::Vector3d& point, double reference_emission_s) {
    const Eigen::Vector3d to_point = point - doa.model.centre_m;
    const double range = std::max(to_point.norm(), 1.0);
    const double emission_s = doa.time_s - range / doa.model.speed_of_sound_mps;
    const double motion_m = params.init_max_speed_mps * std::abs(emission_s - reference_emission_s);
    const MeasurementCovariance r =
        doa.noise + MeasurementCovariance::Identity() * std::pow(motion_m / range, 2);
    const Measurement residual = doa.model.residual(doa.z, doa.model.predict_direction(to_point));
    return residual.dot(r.ldlt().solve(residual));
  };
  const Eigen::Vector3d seed_centre = seed.model.centre_m;
  const auto emission_of = [&](const Eigen::Vector3d& point) {
    return time_s - (point - seed_centre).norm() / models[array].speed_of_sound_mps;
  };

  // How many arrays other than the pair have an unclaimed recent DOA within the gate of `point`.
  const auto agreeing_arrays = [&](const Eigen::Vector3d& point, int first, int second) {
    int count = 0;
    for (int other = 0; other < array_count; ++other) {
      if (other == first || other == second) continue;
      RecentRing& ring = recent[other];
      for (std::size_t i = 0; i < ring.size(); ++i) {
        if (ring[i].used || ring[i].associated) continue;
        if (std::abs(time_s - ring[i].time_s) > params.init_pair_window_s) continue;
        if (chi2_against(ring[i], other, point, emission_of(point)) <=
            gate_for(ring[i].model.dimension())) {
          ++count;
          break;
        }
      }
    }
    return count;
  };
  struct Candidate {
    Triangulation fix;
    int partner_array = -1;
    std::size_t partner_index = 0;
    double score = std::numeric_limits<double>::infinity();
    int agreeing = -1;
    int seed_image = 0;
    int partner_image = 0;
  };
  Candidate best;
  // A planar array's DOA is two rays (it and its mirror image): each pairing tries both; a cone
  // is no ray and never pairs (its display direction is one point of a surface).
  for (int other = 0; other < array_count; ++other) {
    if (other == array) continue;
    RecentRing& ring = recent[other];
    for (std::size_t i = 0; i < ring.size(); ++i) {
      RecentDoa& partner = ring[i];
      if (partner.used || (partner.associated && partner.weak_claimant_id < 0)) continue;
      const double dt = std::abs(time_s - partner.time_s);
      if (dt > params.init_pair_window_s) continue;
      for (int seed_image = 0; seed_image < seed.image_count(); ++seed_image) {
        for (int partner_image = 0; partner_image < partner.image_count(); ++partner_image) {
          std::array<Ray, 2> pair{
              Ray{seed.model.centre_m, seed.image(seed_image), seed.noise},
              Ray{partner.model.centre_m, partner.image(partner_image), partner.noise}};
          const auto fix = triangulate(pair, params.triangulation);
          if (!fix || !fix->in_front) continue;
          const Eigen::Vector3d p = fix->position_m;
          if ((p - seed.model.centre_m).norm() > params.init_max_range_m) continue;
          if (below_ground(*fix)) {
            ++counters.below_ground_rejected;
            continue;
          }
          const double reference = emission_of(p);
          const double chi2 =
              chi2_against(seed, array, p, reference) + chi2_against(partner, other, p, reference);
          // Two rays, three unknowns: one degree of freedom left to test consistency.
          if (chi2 > chi_square_quantile(params.gate_probability, 1)) continue;
          // Where two drones' rays cross, the crossing fits its two rays as well as either drone
          // fits its own: prefer the point more of the other arrays agree with (issue 14's
          // ghosts).
          const int agreeing = agreeing_arrays(p, array, other);
          if (agreeing > best.agreeing || (agreeing == best.agreeing && chi2 < best.score))
            best = {*fix, other, i, chi2, agreeing, seed_image, partner_image};
        }
      }
    }
  }
  if (best.partner_array < 0) return false;

  // Other arrays' unclaimed DOAs that agree with the point sharpen the fix and count toward
  // the arrays that support the new track.
  rays.clear();
  rays.push_back({seed.model.centre_m, seed.image(best.seed_image), seed.noise});
  const RecentDoa& partner = recent[best.partner_array][best.partner_index];
  rays.push_back({partner.model.centre_m, partner.image(best.partner_image), partner.noise});
  std::array<int, kMaxArrays> extra_index{};
  extra_index.fill(-1);
  for (int other = 0; other < array_count; ++other) {
    if (other == array || other == best.partner_array) continue;
    RecentRing& ring = recent[other];
    bool heard = false;
    double best_chi2 = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const double dt = std::abs(time_s - ring[i].time_s);
      if (dt > params.init_pair_window_s) continue;
      heard = true;
      const double chi2 =
          chi2_against(ring[i], other, best.fix.position_m, emission_of(best.fix.position_m));
      if (chi2 < best_chi2) {
        best_chi2 = chi2;
        extra_index[other] = static_cast<int>(i);
      }
    }
    // No agreement is not proof of a ghost: with one or two DOAs per frame, a louder drone can
    // mask this one at that array. Continuity decides (confirm_min_arrays).
    if (!heard || extra_index[other] < 0 ||
        best_chi2 >
            gate_for(ring[static_cast<std::size_t>(extra_index[other])].model.dimension())) {
      extra_index[other] = -1;
      continue;
    }
    const RecentDoa& agreeing = ring[static_cast<std::size_t>(extra_index[other])];
    if (!agreeing.used && !agreeing.associated) {
      // A cone supports the point but is no ray; a planar array's image on the point's side is.
      if (agreeing.image_count() > 0) {
        const Eigen::Vector3d to_point = best.fix.position_m - agreeing.model.centre_m;
        const bool mirrored =
            agreeing.image_count() == 2 &&
            to_point.dot(agreeing.model.axis) * agreeing.direction.dot(agreeing.model.axis) < 0.0;
        rays.push_back({agreeing.model.centre_m, agreeing.image(mirrored ? 1 : 0), agreeing.noise});
      }
    } else {
      extra_index[other] = -1;
    }
  }
  Triangulation fix = best.fix;
  if (rays.size() > 2) {
    if (auto refined = triangulate_least_squares(rays)) fix = *refined;
  }

  if (below_ground(fix)) {  // the further arrays moved it under the ground
    ++counters.below_ground_rejected;
    return false;
  }

  // Not a new drone if an existing track already explains the point.
  for (const Track& track : tracks) {
    const Eigen::Vector3d difference = position_of(track.filter->mean()) - fix.position_m;
    const Eigen::Matrix3d spread =
        track.filter->covariance().topLeftCorner<3, 3>() + fix.covariance_m2;
    if (difference.dot(spread.ldlt().solve(difference)) < chi_square_quantile(0.999, 3)) {
      return false;
    }
  }

  StateVector mean;
  StateCovariance covariance;
  state_from_fix(fix, seed_centre, models[array].speed_of_sound_mps, mean, covariance);

  Track track;
  track.id = next_id++;
  FilterSettings settings = filter_settings;
  settings.random_seed = static_cast<std::uint64_t>(track.id);
  track.filter = make_track_filter(params.filter, settings);
  track.filter->initialise(mean, covariance);
  track.time_s = time_s;
  track.last_update_s = time_s;
  track.heard_by_array_s.fill(kNeverS);
  const auto seed_support = [this, &track, time_s](int supporting_array, const RecentDoa& doa) {
    record_update(track, supporting_array, doa.acoustic, time_s);
    track.birth_arrays |= std::uint64_t{1} << supporting_array;
  };
  seed_support(array, seed);
  seed_support(best.partner_array, partner);
  for (int other = 0; other < array_count; ++other) {
    if (extra_index[other] >= 0)
      seed_support(other, recent[other][static_cast<std::size_t>(extra_index[other])]);
  }
  tracks.push_back(std::move(track));  // confirmed by life_cycle
  ++counters.tracks_started;

  seed.used = true;
  RecentDoa& partner_used = recent[best.partner_array][best.partner_index];
  partner_used.used = true;
  // The partner's tentative track had only one array since its first pair; the new track has
  // that array and another one now: it replaces it (else the older, sharper-looking one keeps
  // the array's DOAs by the assignment's cost and neither is ever confirmed).
  if (partner_used.weak_claimant_id >= 0) {
    const int replaced = partner_used.weak_claimant_id;
    const auto before = tracks.size();
    std::erase_if(tracks, [this, replaced](const Track& other) {
      return other.id == replaced && held_by_one_array(other);
    });
    counters.ghosts_rejected += static_cast<std::int64_t>(before - tracks.size());
    counters.tracks_deleted += static_cast<std::int64_t>(before - tracks.size());
  }
  for (int other = 0; other < array_count; ++other) {
    if (extra_index[other] >= 0) {
      recent[other][static_cast<std::size_t>(extra_index[other])].used = true;
    }
  }
  return true;
}

bool FusionEngine::Impl::try_start_one_array(int array, std::size_t recent_index, double time_s) {
  if (tracks.size() >= static_cast<std::size_t>(params.max_tracks)) return false;
  RecentDoa& seed = recent[array][recent_index];
  const DoaMeasurementModel& model = seed.model;
  const double gate = gate_for(model.dimension());
  // Not a new source if a track already explains the DOA: its predicted reading from this array,
  // with its position spread seen from its range, fits.
  for (const Track& track : tracks) {
    const Eigen::Vector3d to_track = position_of(track.filter->mean()) - model.centre_m;
    const double range_m = std::max(to_track.norm(), 1.0);
    const double spread_m2 = track.filter->covariance().topLeftCorner<3, 3>().trace() / 3.0;
    MeasurementCovariance r = seed.noise;
    r(0, 0) += spread_m2 / (range_m * range_m);
    if (model.dimension() == 2) r(1, 1) += spread_m2 / (range_m * range_m);
    const Measurement residual = model.residual(seed.z, model.predict_direction(to_track));
    if (residual.dot(r.ldlt().solve(residual)) <= gate) return false;
  }
  const double angle_std_rad =
      std::sqrt(model.dimension() == 1 ? seed.noise(0, 0) : 0.5 * seed.noise.trace());
  auto locus = bearing_locus(model, seed.z, angle_std_rad, seed.direction,
                             params.single_array.source_plane_z_m);
  if (!locus) return false;  // a cone with no source plane cannot start a track
  // No hypothesis under the ground: a ground echo's ray (the image a node reports as a second
  // source) then starts nothing.
  if (!params.single_array.source_plane_z_m) locus->min_altitude_m = params.ground_altitude_m;
  Track track;
  track.id = next_id;
  FilterSettings settings = one_array_settings;
  settings.random_seed = static_cast<std::uint64_t>(track.id);
  track.filter = make_track_filter(params.single_array_filter, settings);
  if (!track.filter->initialise_from_bearing(*locus)) return false;
  ++next_id;
  track.one_array = true;
  track.origin_array = array;
  track.origin_noise = seed.noise;
  track.time_s = time_s;
  track.last_update_s = time_s;
  track.heard_by_array_s.fill(kNeverS);
  record_update(track, array, seed.acoustic, time_s);
  tracks.push_back(std::move(track));
  ++counters.tracks_started;
  seed.used = true;
  return true;
}

}  // namespace dronetrack::fusion
