// The tracker: a reorder buffer feeding frames (one array, one time) oldest first into a short
// loop of named stages (process_frame): predict every track to the frame time and gate, check the
// array for a mirror swap, assign (Hungarian), update, follow manoeuvres, remember the DOAs and
// initiate from the unclaimed ones by triangulation; then the life cycle (confirm, coast, delete).
// The stages' state: fusion_engine_impl.hpp; initiation, hand-over, manoeuvre onset and the life
// cycle live in their own files (fusion/README.md).
#include "fusion/fusion_engine.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <tuple>

#include "fusion/doa_admission.hpp"
#include "fusion/fusion_engine_impl.hpp"

namespace dronetrack::fusion {

namespace {

DoaVerdict count_verdict(FusionCounters& counters, DoaVerdict verdict) {
  // In the enum's order; accepted is counted where the DOA is taken.
  static_assert(static_cast<int>(DoaVerdict::bad_direction) == 5);
  std::int64_t* const rejected[] = {nullptr,
                                    &counters.rejected_non_finite,
                                    &counters.rejected_unknown_array,
                                    &counters.rejected_too_late,
                                    &counters.rejected_duplicate,
                                    &counters.rejected_bad_direction};
  if (std::int64_t* counter = rejected[static_cast<std::size_t>(verdict)]) ++*counter;
  return verdict;
}
}  // namespace

FusionEngine::FusionEngine(const FusionParams& params, std::vector<doa::ArrayGeometry> arrays,
                           double speed_of_sound_mps)
    : impl_(std::make_unique<Impl>()) {
  const OneArrayParams& one = params.single_array;
  const std::size_t min_arrays = params.single_array_start ? 1 : 2;
  if (arrays.size() < min_arrays || arrays.size() > static_cast<std::size_t>(kMaxArrays)) {
    throw std::invalid_argument(
        "arrays: fusion needs 2 to 64 arrays (1 with single_array_start), got " +
        std::to_string(arrays.size()));
  }
  Impl& s = *impl_;
  s.params = params;
  s.arrays = std::move(arrays);
  for (const auto& array : s.arrays) {
    s.models.push_back(
        {array.centre_site_m(), speed_of_sound_mps, params.model_propagation_delay ? 3 : 0});
  }
  s.filter_settings.motion.jerk_variance_m2ps6 =
      params.jerk_noise_std_mps3 * params.jerk_noise_std_mps3;
  s.filter_settings.ukf_alpha = params.ukf_alpha;
  s.filter_settings.ukf_beta = params.ukf_beta;
  s.filter_settings.ukf_kappa = params.ukf_kappa;
  s.filter_settings.particle_count = params.particle_count;
  s.likelihood.emplace(params.likelihood, params.student_t_dof, params.outlier_probability,
                       params.gate_probability);
  s.filter_settings.likelihood = *s.likelihood;
  s.filter_settings.imm_jerk_std_mps3 = params.imm_jerk_std_mps3;
  if (params.imm_jerk_std_mps3.size() == 1) {  // one level: a single model at that level
    s.filter_settings.motion.jerk_variance_m2ps6 = std::pow(params.imm_jerk_std_mps3[0], 2);
  }
  s.filter_settings.imm_sojourn_s = params.imm_sojourn_s;
  if (params.imm_turn_mode) {
    s.filter_settings.imm_turn_rate_std_radps2 = params.imm_turn_rate_std_radps2;
  }
  s.filter_settings.imm_turn_jerk_std_mps3 = params.imm_turn_jerk_std_mps3;
  s.classifier.emplace(params.classifier, params.ground_altitude_m);
  s.gate_chi2 = chi_square_quantile(params.gate_probability, 2);
  s.gate_chi2_1d = chi_square_quantile(params.gate_probability, 1);
  // The one-array localisers run one constant-jerk model (static and slow sources) with their own
  // prior, particle count and the source plane.
  s.one_array_settings = s.filter_settings;
  s.one_array_settings.imm_jerk_std_mps3.clear();
  s.one_array_settings.imm_turn_rate_std_radps2.clear();
  s.one_array_settings.motion_kind = MotionKind::constant_jerk;
  s.one_array_settings.motion.jerk_variance_m2ps6 = one.jerk_std_mps3 * one.jerk_std_mps3;
  s.one_array_settings.particle_count = one.particle_count;
  s.one_array_settings.one_array = one;
  // No track is placed farther from every array than init_max_range_m: nor a hypothesis.
  s.one_array_settings.one_array.max_range_m = std::min(one.max_range_m, params.init_max_range_m);
  s.one_array_settings.one_array.max_speed_mps = params.init_max_speed_mps;
  for (const auto& model : s.models) s.last_centre_m.push_back(model.centre_m);
  s.floor_variance_rad2 = std::pow(params.doa_noise_floor_deg * kRadPerDeg, 2);
  s.confirmation.emplace(params, s.floor_variance_rad2, s.gate_chi2, speed_of_sound_mps);
  {
    double widest_jerk = params.jerk_noise_std_mps3;
    for (double level : params.imm_jerk_std_mps3) widest_jerk = std::max(widest_jerk, level);
    ConstantJerkModel manoeuvre;
    manoeuvre.jerk_variance_m2ps6 = widest_jerk * widest_jerk;
    s.manoeuvre_noise = manoeuvre.process_noise(kManoeuvreSpanS);
    s.manoeuvre_position_variance_m2 = s.manoeuvre_noise(0, 0);
  }
  s.last_fed_time_by_array.assign(s.arrays.size(), kNeverS);
  s.last_fed_sources_by_array.assign(s.arrays.size(), 0);
  s.recent.resize(s.arrays.size());
  s.queue.reserve(1024);
  for (std::size_t a = 0; a < s.arrays.size(); ++a)
    s.mirror_checks.emplace_back(static_cast<int>(a), s.arrays[a], params.mirror_check);
  if (params.likelihood == DoaLikelihoodKind::outlier_mixture &&
      params.adaptive_outlier_probability) {
    s.outlier_shares.reserve(s.arrays.size());
    for (std::size_t a = 0; a < s.arrays.size(); ++a)
      s.outlier_shares.emplace_back(params.outlier_probability, params.outlier_prior_doas,
                                    params.outlier_window_doas);
  }
  s.references.reserve(static_cast<std::size_t>(params.max_tracks));
  s.mirror_events.reserve(16);
  s.pending_seeds.reserve(kMaxPendingSeeds);
  s.pending_single_seeds.reserve(kMaxPendingSeeds);
  s.tracks.reserve(static_cast<std::size_t>(params.max_tracks));
}

FusionEngine::~FusionEngine() = default;
FusionEngine::FusionEngine(FusionEngine&&) noexcept = default;
FusionEngine& FusionEngine::operator=(FusionEngine&&) noexcept = default;

DoaVerdict FusionEngine::admit(const doa::DoaMeasurement& measurement) {
  int index = -1;
  const DoaVerdict verdict = check_doa(measurement, impl_->arrays, index);
  if (verdict == DoaVerdict::accepted) ++impl_->counters.accepted;
  return count_verdict(impl_->counters, verdict);
}

DoaVerdict FusionEngine::add(const doa::DoaMeasurement& measurement) {
  Impl& s = *impl_;
  auto reject = [&s](DoaVerdict verdict) { return count_verdict(s.counters, verdict); };
  int index = -1;
  if (const DoaVerdict verdict = check_doa(measurement, s.arrays, index);
      verdict != DoaVerdict::accepted)
    return reject(verdict);
  if (measurement.time_s < s.fed_time_s) return reject(DoaVerdict::too_late);
  const std::uint64_t source_bit = std::uint64_t{1} << measurement.source_index;
  if (measurement.time_s == s.last_fed_time_by_array[index] &&
      (s.last_fed_sources_by_array[index] & source_bit) != 0) {
    return reject(DoaVerdict::duplicate);
  }
  const auto key = [](const doa::DoaMeasurement& m) {
    return std::make_tuple(m.time_s, m.array_index, m.source_index);
  };
  doa::DoaMeasurement queued = measurement;
  queued.array_index = index;
  queued.direction.normalize();
  const auto position =
      std::upper_bound(s.queue.begin(), s.queue.end(), queued,
                       [&key](const doa::DoaMeasurement& a, const doa::DoaMeasurement& b) {
                         return key(a) < key(b);
                       });
  if (position != s.queue.begin() && key(*(position - 1)) == key(queued)) {
    return reject(DoaVerdict::duplicate);
  }
  s.queue.insert(position, std::move(queued));
  ++s.counters.accepted;
  return DoaVerdict::accepted;
}

void FusionEngine::advance_to(double time_s) {
  if (!std::isfinite(time_s)) return;
  impl_->feed_until(time_s - impl_->params.reorder_window_s);
}

void FusionEngine::Impl::feed_until(double cutoff_s) {
  std::size_t begin = 0;
  while (begin < queue.size() && queue[begin].time_s <= cutoff_s) {
    std::size_t end = begin + 1;
    while (end < queue.size() && queue[end].time_s == queue[begin].time_s &&
           queue[end].array_index == queue[begin].array_index) {
      ++end;
    }
    const double frame_time_s = queue[begin].time_s;
    delete_expired(frame_time_s);
    process_frame(begin, end);
    confirm_tracks(frame_time_s);
    mark_duplicates(frame_time_s);
    begin = end;
  }
  queue.erase(queue.begin(), queue.begin() + static_cast<std::ptrdiff_t>(begin));
  if (cutoff_s > fed_time_s) life_cycle(cutoff_s);
}

void FusionEngine::Impl::process_frame(std::size_t begin, std::size_t end) {
  const Frame frame = begin_frame(begin, end);
  gate(frame);
  check_mirror(frame.array, begin, end, frame.time_s);
  assignment.solve(cost, frame.track_count, frame.doa_count, track_to_doa);
  update_assigned(frame);
  follow_manoeuvres(frame);
  if (frame.outlier_share) frame.outlier_share->refresh();
  // Unassigned DOAs: remember them, and try to start a track with other arrays' recent DOAs.
  remember(frame);
  initiate_pending();
}

Frame FusionEngine::Impl::begin_frame(std::size_t begin, std::size_t end) {
  Frame frame;
  frame.begin = begin;
  frame.end = end;
  const int array = frame.array = queue[begin].array_index;
  const double time_s = frame.time_s = queue[begin].time_s;
  frame.doa_count = static_cast<int>(end - begin);
  frame.track_count = static_cast<int>(tracks.size());
  fed_time_s = std::max(fed_time_s, time_s);
  if (last_fed_time_by_array[array] != time_s) last_fed_sources_by_array[array] = 0;
  last_fed_time_by_array[array] = time_s;
  for (std::size_t i = begin; i < end; ++i) {
    last_fed_sources_by_array[array] |= std::uint64_t{1} << queue[i].source_index;
  }
  // Every DOA of a frame shares its array's pose; a DOA of another ambiguity kind than the
  // frame's first (not expected from one array) is kept out of the assignment.
  frame_model = model_of(queue[begin]);
  last_centre_m[static_cast<std::size_t>(array)] = frame_model.centre_m;
  frame.dimension = frame_model.dimension();
  frame.ambiguity = queue[begin].ambiguity;
  frame.outlier_share =
      outlier_shares.empty() ? nullptr : &outlier_shares[static_cast<std::size_t>(array)];
  if (frame.outlier_share) frame.share = frame.outlier_share->share();
  return frame;
}

void FusionEngine::Impl::gate(const Frame& frame) {
  const auto& [begin, end, array, time_s, doa_count, track_count, dimension, ambiguity,
               outlier_share, share] = frame;
  const DoaMeasurementModel& model = frame_model;
  cost.assign(static_cast<std::size_t>(track_count) * doa_count, kForbidden);
  distance2.assign(cost.size(), std::numeric_limits<double>::infinity());
  for (int t = 0; t < track_count; ++t) {
    Track& track = tracks[t];
    track.filter->predict(time_s - track.time_s);
    track.time_s = time_s;
    track.inflation = correlation_inflation(track, array, time_s);
    const FilterStatus status =
        track.filter->innovation(model, floor_of(queue[begin], track.inflation), track.innovation);
    note(status);
    track.innovation_ok = status != FilterStatus::failed;
    if (!track.innovation_ok) continue;
    const Measurement& azel = track.innovation.predicted;
    track.predicted_direction =
        doa::direction_from_azel_deg(azel(0) / kRadPerDeg, azel(1) / kRadPerDeg);
    for (int j = 0; j < doa_count; ++j) {
      const doa::DoaMeasurement& m = queue[begin + j];
      if (m.ambiguity != ambiguity) continue;
      Innovation candidate = track.innovation;
      candidate.covariance += track.inflation * own_noise(m);
      const double d2 = candidate.mahalanobis2(measured(m));
      distance2[static_cast<std::size_t>(t) * doa_count + j] = d2;
      if (d2 <= likelihood->gate_d2(dimension)) {
        cost[static_cast<std::size_t>(t) * doa_count + j] = likelihood->assignment_cost(
            d2, std::log(candidate.covariance.determinant()), dimension, share);
      }
    }
  }
}

void FusionEngine::Impl::update_assigned(const Frame& frame) {
  const auto& [begin, end, array, time_s, doa_count, track_count, dimension, ambiguity,
               outlier_share, share] = frame;
  const DoaMeasurementModel& model = frame_model;
  doa_taken.assign(static_cast<std::size_t>(doa_count), 0);
  doa_confirmed.assign(static_cast<std::size_t>(doa_count), 0);
  for (int t = 0; t < track_count; ++t) {
    if (tracks[t].confirmed && track_to_doa[t] >= 0)
      doa_confirmed[static_cast<std::size_t>(track_to_doa[t])] = 1;
  }
  weak_claimant.assign(static_cast<std::size_t>(doa_count), -1);
  int confirmed_heard = 0;  // confirmed tracks this array hears
  for (const Track& track : tracks) {
    if (track.confirmed && time_s - track.heard_by_array_s[array] <= kContributionMemoryS)
      ++confirmed_heard;
  }
  const bool crowded = doa_count <= confirmed_heard;
  // A confirmed track this array hears that got no DOA from this frame, within kBesideAngleRad
  // of `direction`: an impulsive error of its source (reflection, gust) lands around it.
  const auto beside_missed_track = [&](const Eigen::Vector3d& direction) {
    for (int t = 0; t < frame.track_count; ++t) {
      const Track& other = tracks[t];
      if (!other.confirmed || track_to_doa[t] >= 0 || !other.innovation_ok ||
          frame.time_s - other.heard_by_array_s[frame.array] > kContributionMemoryS)
        continue;
      if (other.predicted_direction.dot(direction) >= beside_cosine) return true;
    }
    return false;
  };
  for (int t = 0; t < track_count; ++t) {
    Track& track = tracks[t];
    track.hits_by_array[array] <<= 1;
    const int j = track_to_doa[t];
    if (j < 0) continue;
    const doa::DoaMeasurement& m = queue[begin + j];
    const int single = track.one_array ? track.origin_array : open_range_array(track);
    if (single >= 0 && array != single &&
        refix_by_triangulation(track, single,
                               track.one_array ? track.origin_noise : floor_of(m, 1.0), m, model,
                               time_s)) {
      doa_taken[j] = 1;
      record_update(track, array, m.acoustic, time_s);
      continue;
    }
    Innovation innovation = track.innovation;
    innovation.covariance += track.inflation * own_noise(m);
    innovation.noise = track.inflation * noise_of(m);
    if (m.ambiguity == doa::DoaAmbiguity::cone) innovation.noise(1, 1) = 1.0;  // the pad
    innovation.outlier_probability = share;
    const Measurement z = measured(m);
    // A confirmed track's gated DOAs inform the array's e (another source's DOA in the gate is an
    // outlier for this track, which is what e models). A tentative track may be a ghost, whose
    // "inliers" are nobody's.
    if (outlier_share && track.confirmed) {
      outlier_share->add(likelihood->outlier_density_ratio(
          distance2[static_cast<std::size_t>(t) * doa_count + j], dimension));
    }
    // The filter weighs z by the DOA likelihood itself (FilterSettings::likelihood).
    const FilterStatus status = track.filter->update_with_peaks(innovation, z, peaks_of(m));
    note(status);
    doa_taken[j] = 1;  // gated to a live track: never an initiation seed, even if refused
    if (held_by_one_array(track)) weak_claimant[j] = track.id;
    if (status == FilterStatus::failed) continue;
    record_update(track, array, m.acoustic, time_s);
    if (crowded && !track.confirmed && beside_missed_track(m.direction)) ++track.crowded_updates;
    if (track.one_array) {
      if (log::level() <= log::Level::debug) log_branches(track, time_s);
      hand_over(track);
    }
  }
}

void FusionEngine::Impl::follow_manoeuvres(const Frame& frame) {
  const auto& [begin, end, array, time_s, doa_count, track_count, dimension, ambiguity,
               outlier_share, share] = frame;
  for (int t = 0; t < track_count; ++t) {
    const std::uint64_t bit = std::uint64_t{1} << array;
    Track& track = tracks[t];
    if (track_to_doa[t] >= 0 || !track.confirmed || track.one_array || !track.innovation_ok ||
        dimension != 2) {
      track.unexplained_arrays &= ~bit;
      continue;
    }
    const int j = follow_manoeuvre(track, array, begin, doa_count, time_s);
    if (j >= 0)
      doa_taken[static_cast<std::size_t>(j)] = doa_confirmed[static_cast<std::size_t>(j)] = 1;
  }
}

void FusionEngine::Impl::remember(const Frame& frame) {
  const auto& [begin, end, array, time_s, doa_count, track_count, dimension, ambiguity,
               outlier_share, share] = frame;
  RecentRing& ring = recent[array];
  counters.gated_out += ring.expire(time_s - 2.0 * params.init_pair_window_s);
  for (int j = 0; j < doa_count; ++j) {
    const doa::DoaMeasurement& m = queue[begin + j];
    RecentDoa entry;
    entry.time_s = time_s;
    entry.direction = m.direction;
    entry.model = model_of(m);
    entry.z = measured(m);
    entry.noise = noise_of(m);
    entry.associated = doa_taken[j] != 0;
    entry.weak_claimant_id = weak_claimant[j];
    entry.acoustic = m.acoustic;
    const std::uint64_t sequence = ring.push(entry);
    if (!entry.associated && entry.image_count() > 0 && pending_seeds.size() < kMaxPendingSeeds)
      pending_seeds.push_back({array, sequence, time_s});
    if (!entry.associated && params.single_array_start &&
        pending_single_seeds.size() < kMaxPendingSeeds)
      pending_single_seeds.push_back({array, sequence, time_s});
  }
}

void FusionEngine::Impl::check_mirror(int array, std::size_t begin, std::size_t end,
                                      double time_s) {
  ArrayMirrorCheck& check = mirror_checks[static_cast<std::size_t>(array)];
  const MirrorCheckSettings& settings = params.mirror_check;
  if (!settings.enabled || check.mirrors() == 0 || frame_model.kind != MeasurementKind::azel)
    return;
  references.clear();
  const double max_angle_rad = settings.max_track_angle_deg * kRadPerDeg;
  for (const Track& track : tracks) {
    if (!track.confirmed || !track.innovation_ok) continue;
    int others = 0;
    for (std::size_t a = 0; a < arrays.size(); ++a) {
      if (static_cast<int>(a) != array &&
          time_s - track.heard_by_array_s[a] <= kContributionMemoryS)
        ++others;
    }
    if (others < settings.min_other_arrays) continue;
    const Eigen::Vector3d offset_m = position_of(track.filter->mean()) - frame_model.centre_m;
    const double range_m = offset_m.norm();
    if (!(range_m > 0.0)) continue;
    // Only the spread across the judged array's ray turns its direction; the spread along the
    // ray (the other arrays' range error) does not, so it must not keep a track out.
    const Eigen::Matrix3d position_covariance = track.filter->covariance().topLeftCorner<3, 3>();
    const Eigen::Vector3d ray = offset_m / range_m;
    const double across_m2 =
        0.5 * (position_covariance.trace() - ray.dot(position_covariance * ray));
    if (!(std::sqrt(std::max(across_m2, 0.0)) <= max_angle_rad * range_m)) continue;
    references.push_back(track.predicted_direction);
  }
  if (references.empty()) return;
  const doa::PoseStamp& pose = queue[begin].pose;
  const Eigen::Matrix3d attitude = pose.moving
                                       ? pose.array_to_site.toRotationMatrix()
                                       : arrays[static_cast<std::size_t>(array)].array_to_site();
  for (std::size_t i = begin; i < end; ++i) {
    if (queue[i].ambiguity != doa::DoaAmbiguity::none) continue;
    check.observe(time_s, queue[i].direction, attitude, references);
  }
  for (const MirrorSwapEvent& event : check.events()) mirror_events.push_back(event);
  check.clear_events();
}

void FusionEngine::take_mirror_events(std::vector<MirrorSwapEvent>& out) {
  out.insert(out.end(), impl_->mirror_events.begin(), impl_->mirror_events.end());
  impl_->mirror_events.clear();
}

const MirrorCheckStatus& FusionEngine::mirror_status(std::size_t array) const {
  return impl_->mirror_checks.at(array).status();
}

double FusionEngine::outlier_share(std::size_t array) const {
  const Impl& s = *impl_;
  if (!s.outlier_shares.empty()) return s.outlier_shares.at(array).share();
  return s.params.likelihood == DoaLikelihoodKind::outlier_mixture ? s.params.outlier_probability
                                                                   : 0.0;
}

void FusionEngine::tracks_at(double time_s, std::vector<TrackReport>& out) const {
  const Impl& s = *impl_;
  out.clear();
  for (const Track& track : s.tracks) {
    TrackReport report;
    report.id = track.id;
    report.time_s = time_s;
    StateVector mean = track.filter->mean();
    StateCovariance covariance = track.filter->covariance();
    s.filter_settings.motion.predict(mean, covariance, std::max(time_s - track.time_s, 0.0));
    report.position_m = position_of(mean);
    report.velocity_mps = velocity_of(mean);
    report.acceleration_mps2 = acceleration_of(mean);
    report.covariance = covariance;
    report.last_update_s = track.last_update_s;
    report.track_class = track.evidence.track_class;
    report.class_confidence = track.evidence.confidence;
    report.confirmed_s = track.confirmed ? time_s - track.confirmed_at_s : -1.0;
    report.one_array = track.one_array;
    report.hypotheses = track.filter->hypothesis_count();
    if (!track.confirmed) {
      report.status = TrackStatus::tentative;
    } else if (time_s - track.last_update_s > s.params.coast_after_s) {
      report.status = TrackStatus::coasting;
    } else {
      report.status = TrackStatus::confirmed;
    }
    for (std::size_t a = 0; a < s.arrays.size(); ++a) {
      if (time_s - track.heard_by_array_s[a] <= kContributionMemoryS) {
        report.contributing_arrays |= std::uint64_t{1} << a;
      }
    }
    out.push_back(report);
  }
}

const FusionCounters& FusionEngine::counters() const { return impl_->counters; }
const std::vector<doa::ArrayGeometry>& FusionEngine::arrays() const { return impl_->arrays; }

}  // namespace dronetrack::fusion
