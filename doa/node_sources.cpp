// NodePipeline's source stages: the frame's sources found (the tracker's, then SRP-PHAT's
// further looks with the louder sources' bins dropped), each freed of its ground echo and
// measured again on its own bins, smoothed over frames, published.
#include "doa/node_pipeline_impl.hpp"

#include <algorithm>
#include <numeric>

#include "doa/comb_line_cleaning.hpp"
#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

// The static null learns from plain PHAT peaks: a steady ground source is as steady in power as
// the noise floor, so the SNR weights fade it and it would rarely be the strongest. It learns
// over seconds, so one look every kStaticNullLookFrames frames is enough, and a look the frame
// makes anyway serves: the plain re-correlation without the first source's bins (a drone's
// bins gone, the ground source stands out more than in the full band), or the weighted look
// itself when its strongest source is below the horizon (it is the ground source). Only a
// frame without either gets a plain look of its own (null_own_look).
void NodePipeline::Impl::null_observe() {
  double peak_sum = 0.0;
  for (int p = 0; p < gcc.pair_count(); ++p) peak_sum += gcc.pair(p).peak.value;
  static_null->observe(null_time_s, gcc,
                       null_frame_clean && peak_sum >= params.min_gcc_peak * gcc.pair_count());
  diagnostics.static_sources_nulled = static_null->nulled_count();
  null_observed = true;
}

// The full band in plain PHAT with only the static null's mask, as whiten() and mask() left
// it (keep_frame_mask() in analyse()).
void NodePipeline::Impl::null_own_look() {
  gcc.cross_power(gcc.units(), frame_mask);
  gcc.correlate(true, false);
  null_observe();
}

double NodePipeline::Impl::inband_power() {
  // Parseval: one-sided bins count twice; per windowed sample.
  const double scale = 2.0 / (static_cast<double>(fft.fft_size()) * fft.window_energy());
  // whiten()'s |X|^2 rows (every mic is in a pair: one row per channel).
  const auto bins = static_cast<std::size_t>(gcc.band_bin_count());
  const std::span<const double> powers = gcc.band_powers();
  double total = 0.0;
  for (int c = 0; c < fft.channels(); ++c) {
    const std::span<const double> row = powers.subspan(static_cast<std::size_t>(c) * bins, bins);
    const double power = std::accumulate(row.begin(), row.end(), 0.0);
    channel_power[static_cast<std::size_t>(c)] = scale * power;
    total += power;
  }
  return scale * total / fft.channels();
}

bool NodePipeline::Impl::sharp_either_sign() const {
  double sum = 0.0;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairPeak& pair = health_pairs[static_cast<std::size_t>(p)];
    sum += std::max(pair.highest, -pair.lowest);
  }
  return sum >= params.min_gcc_peak * gcc.pair_count();
}

bool NodePipeline::Impl::publish(const Candidate& candidate, double time_s, int source_index,
                                 std::vector<DoaMeasurement>& out) {
  const DoaSolution solution = doppler_corrected(candidate, time_s);
  const std::span<const PairTdoa> used(candidate.tdoas.data(), tdoas.size());
  DoaMeasurement measurement;
  measurement.array_id = geometry.id;
  measurement.array_index = array_index;
  measurement.time_s = time_s - geometry.clock_offset_s;  // on the site's clock
  measurement.direction = solution.direction_site;
  measurement.azel_covariance_rad2 = solution.azel_covariance_rad2;
  measurement.quality = solution.quality;
  measurement.snr_db = gate.snr_db();
  measurement.source_index = source_index;
  measurement.ambiguity = solution.ambiguity;
  measurement.ambiguity_axis = solution.ambiguity_axis_site;
  measurement.cone_angle_rad = solution.cone_angle_rad;
  measurement.cone_angle_variance_rad2 = solution.cone_angle_variance_rad2;
  if (cone_peaks) cone_peaks->fill(time_s, measurement);
  measurement.pair_count = solver.pair_count();
  for (int p = 0; p < solver.pair_count(); ++p)
    measurement.tdoa_s[static_cast<std::size_t>(p)] = used[static_cast<std::size_t>(p)].tdoa_s;
  if (acoustic && candidate.slot >= 0) measurement.acoustic = acoustic->features(candidate.slot);
  if (!stamp_pose(measurement)) return false;
  out.push_back(std::move(measurement));
  ++diagnostics.doas_published;
  return true;
}

// Everything before publishing works in the frame of the geometry's fixed attitude (the solver's
// rotation, the ground echo, the horizon); a moving array's DOA is turned to the attitude at its
// time here, and only here.
bool NodePipeline::Impl::stamp_pose(DoaMeasurement& measurement) {
  if (pose_track.empty()) {
    measurement.pose = fixed_pose;
    return true;
  }
  const std::optional<PoseStamp> stamp = pose_track.stamp(measurement.time_s, geometry);
  if (!stamp) {
    ++diagnostics.unposed_doas;
    return false;
  }
  restamp(measurement, *stamp, solver.array_to_site());
  return true;
}

// A platform moving at v towards the source shortens every TDOA alike: measured = true /
// (1 + u.v / c), 0.5 % at 2 m/s. The plane-wave fit is blind to a common scale, but the
// near-field refinement reads it as wavefront curvature and bends the direction (0.7 deg for a
// platform driving at 2 m/s and turning at 15 deg/s), and the chi^2 gate of a plain plane-wave
// fit would refuse it. So: solved again on the TDOAs scaled back by the pose track's velocity,
// with u from the first solve (its error is far below what moves the scale). Only for a full
// direction: a cone or mirror pair does not know u.
DoaSolution NodePipeline::Impl::doppler_corrected(const Candidate& candidate, double time_s) const {
  if (pose_track.empty() || !candidate.solution.accepted ||
      candidate.solution.ambiguity != DoaAmbiguity::none)
    return candidate.solution;
  const std::optional<Eigen::Vector3d> velocity_site = pose_track.velocity_mps(time_s);
  const std::optional<PoseStamp> stamp = pose_track.stamp(time_s, geometry);
  if (!velocity_site || !stamp) return candidate.solution;
  // The solver's frame is the config pose's: the velocity as that frame sees it.
  const Eigen::Vector3d velocity =
      solver.array_to_site() * (stamp->array_to_site.conjugate() * *velocity_site);
  const double scale = 1.0 + candidate.solution.direction_site.dot(velocity) / sound_speed_mps;
  std::array<PairTdoa, kMaxPairs> scaled = candidate.tdoas;
  for (PairTdoa& pair : scaled) pair.tdoa_s *= scale;
  const DoaSolution solution = solver.solve(std::span<const PairTdoa>(scaled.data(), tdoas.size()));
  return solution.accepted ? solution : candidate.solution;
}

double NodePipeline::Impl::mean_coherence(std::span<const PairTdoa> used) const {
  double sum = 0.0;
  int count = 0;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairTdoa& tdoa = used[static_cast<std::size_t>(p)];
    if (!(tdoa.variance_s2 > 0.0)) continue;
    sum += tdoa.coherence;
    ++count;
  }
  return count > 0 ? sum / count : 0.0;
}

void NodePipeline::Impl::accept_candidate() {
  Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
  candidate.coherence =
      mean_coherence(std::span<const PairTdoa>(candidate.tdoas.data(), tdoas.size()));
  candidate.time_offset_s = 0.0;
  ++candidate_count;
}

void NodePipeline::Impl::drop_candidates(int first, int last) {
  for (int s = first; s < last; ++s)
    bin_mask.drop(gcc, std::span<const PairTdoa>(
                           candidates[static_cast<std::size_t>(s)].tdoas.data(), tdoas.size()));
}

// Below the horizon mask a source is on the ground (a generator, a road) or is the ground's
// reflection of a drone (its mirror image, as loud as -6 dB): not a target, and left out of
// the next look's bins. Only a 3-D array knows up from down.
bool NodePipeline::Impl::below_horizon(const DoaSolution& solution) {
  if (solver.rank() < 3 || solution.direction_site.z() >= min_elevation_sine) return false;
  ++diagnostics.below_horizon_rejected;
  return true;
}

// Within srp_min_separation_deg of a source already in this frame's candidates: the same one.
bool NodePipeline::Impl::already_found(const Eigen::Vector3d& direction_site) const {
  for (int s = 0; s < candidate_count; ++s)
    if (direction_site.dot(candidates[static_cast<std::size_t>(s)].solution.direction_site) >=
        separation_cosine)
      return true;
  return false;
}

void NodePipeline::Impl::find_candidates() {
  candidate_count = 0;
  Candidate& primary = candidates[0];
  primary.solution = solver.solve(tdoas);
  const bool primary_below_horizon = primary.solution.accepted && below_horizon(primary.solution);
  trace_look(LookKind::primary, primary.solution, false);
  if (primary_below_horizon && null_wanted) null_observe();
  if (primary_below_horizon) mask_source(tdoas);
  if (primary.solution.accepted && !primary_below_horizon) {
    std::copy(tdoas.begin(), tdoas.end(), primary.tdoas.begin());
    accept_candidate();
  }
  keep_frame_mask();
  const bool under_floor = srp && find_further_sources();
  const int before_static_look = candidate_count;
  if (static_look) find_static_source();
  trace_added(LookKind::static_look, before_static_look);
  // After the static look: a source it holds is not one the own looks found (it would lose
  // its hold on a hovering drone the comb look finds only now and then).
  if (under_floor && comb_look_lines > 0 && candidate_count < params.max_sources)
    comb_look(before_static_look);
  // A frame whose looks gave the static null nothing to observe: its own look, before the echo
  // removal rotates the mics' units.
  if (null_wanted && !null_observed) null_own_look();
  if (!ground_echoes.empty()) remove_ground_echoes();
  trace_candidates();
}

// Each source found takes its bins out of the correlations before the next look: what is left is
// normalised over the bins the louder sources do not own, so a weaker drone's peak is neither
// buried under the louder one's lobes nor pulled by them.
bool NodePipeline::Impl::find_further_sources() {
  if (candidate_count > 0) mask_source(tdoas, null_wanted && !null_observed);
  found_combs.fill(FoundComb{});  // made when first asked for (the follow, the comb look)
  const int before_follow = candidate_count;
  if (source_tracks && params.follow_source_tracks) follow_tracked_sources();
  trace_added(LookKind::followed, before_follow);
  srp->begin_frame(gcc);
  bool under_floor = false;
  // A few more looks than sources: a look whose TDOAs do not fit is cancelled and skipped. At
  // most kMaxFreeLooks in all, whatever max_sources: on a faulty array (a skewed channel) most
  // looks are cancelled, and every further one is a further chance for a spurious source.
  const int looks = std::min(params.max_sources + 2, node_detail::kMaxFreeLooks);
  for (int look = 0; look < looks && candidate_count < params.max_sources; ++look) {
    SrpPeak peak;
    under_floor = !srp->strongest(peak, kept_bins_floor());
    if (under_floor) break;
    const bool duplicate = !solve_look(peak, LookKind::free);
    Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
    const std::span<PairTdoa> candidate_tdoas(candidate.tdoas.data(), tdoas.size());
    if (!duplicate && below_horizon(candidate.solution)) {
      mask_source(candidate_tdoas);
      srp->begin_frame(gcc);
      continue;
    }
    if (duplicate) {
      srp->subtract_direction(gcc, peak.direction_array);
      continue;
    }
    accept_candidate();
    if (candidate_count < params.max_sources) {
      mask_source(candidate_tdoas);
      srp->begin_frame(gcc);
    }
  }
  trace_search_end(under_floor);
  comb_look_lines = 0;
  if (under_floor && own_comb && params.comb_look) mark_comb_look_lines();
  if (candidate_count >= 2) remeasure(0, gcc.units());
  return under_floor;
}

// The TDOAs of the correlation maxima nearest a look's lags, solved into the next candidate's
// place; false when the solver refuses them or they are a source the frame already has.
bool NodePipeline::Impl::solve_look(const SrpPeak& peak, LookKind kind) {
  Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
  const std::span<PairTdoa> candidate_tdoas(candidate.tdoas.data(), tdoas.size());
  srp->tdoas_near(gcc, peak.direction_array, candidate_tdoas);
  candidate.solution = solver.solve(candidate_tdoas);
  if (params.free_look_lobe_choice) choose_lobe(candidate_tdoas, candidate.solution);
  const bool duplicate =
      !candidate.solution.accepted || already_found(candidate.solution.direction_site);
  trace_look(kind, candidate.solution, duplicate, &peak.direction_array);
  return !duplicate;
}

// Incoherent noise over fewer bins correlates more by chance: the SRP floor for the bins the
// last correlation kept. Nothing under it is used: the search may skip what cannot reach it.
double NodePipeline::Impl::kept_bins_floor() const {
  return srp_noise_floor *
         std::sqrt(static_cast<double>(gcc.band_bin_count()) / std::max(1, gcc.kept_bin_count()));
}

// The frame's cross-power again from `units`, minus every other candidate's bins.
bool NodePipeline::Impl::only_bins_of(int source, const GccPhat::UnitsView& units, bool weighted,
                                      CombLines comb_permission) {
  gcc.cross_power(units, frame_mask, weighted);
  drop_candidates(0, source);
  drop_candidates(source + 1, candidate_count);
  return own_comb && comb_permission == CombLines::allowed && candidate_count > 1 &&
         keep_own_comb(source, units);
}

// The source's spectrum is its steered cross-power, bin by bin: sum over pairs of
// |X_i||X_j| cos(phase_ij - w tau_ij) at its TDOAs, large where it dominates, near zero or
// negative where another source or noise does. A rotor's lines stand out of it as a comb; the
// bins between them hold its own broadband and the other sources' broadband and lines (a
// generator's 50 Hz comb, a car's tyres) that pull its peaks towards theirs (docs/doa.md, "Own
// comb bins"). Kept: its lines, and the bins between them whose phasors agree with it on average
// over the pairs as SourceBinMask judges a source's own bin (a lone drone keeps its broadband
// and loses nothing). The lines still hold the other sources' broadband, whose cross-power the
// neighbouring off-line bins estimate: it is taken out of each line's phase
// (subtract_neighbour_cross_power). No comb (a broadband source): nothing dropped.
bool NodePipeline::Impl::keep_own_comb(int source, const GccPhat::UnitsView& units) {
  const Candidate& candidate = candidates[static_cast<std::size_t>(source)];
  const std::span<std::uint8_t> keep = gcc.bin_keep();
  int pairs = 0;
  const HarmonicComb comb = steered_comb(
      std::span<const PairTdoa>(candidate.tdoas.data(), tdoas.size()), units, keep, pairs);
  if (own_comb->mark_lines(comb, comb_lines) < node_detail::kMinOwnCombLines) return false;
  const double own_bin_agreement = node_detail::kOwnBinAgreement * pairs;
  std::size_t index = 0;
  for (const BandRun& run : gcc.band()) {
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      const auto bin = static_cast<std::size_t>(k - comb_first_bin);
      if (comb_lines[bin] == 0 && comb_agreement[bin] < own_bin_agreement) keep[index] = 0;
    }
  }
  subtract_neighbour_cross_power(gcc, units, comb_lines, comb_first_bin);
  return true;
}

HarmonicComb NodePipeline::Impl::steered_comb(std::span<const PairTdoa> source_tdoas,
                                              const GccPhat::UnitsView& units,
                                              std::span<const std::uint8_t> keep, int& pairs) {
  std::fill(comb_power.begin(), comb_power.end(), 0.0);
  std::fill(comb_agreement.begin(), comb_agreement.end(), 0.0);
  pairs = steer(source_tdoas, units, keep, comb_power, comb_agreement);
  for (double& power : comb_power) power = std::max(power, 0.0);
  return own_comb->detect(comb_power);
}

int NodePipeline::Impl::steer(std::span<const PairTdoa> lags, const GccPhat::UnitsView& units,
                              std::span<const std::uint8_t> keep, std::span<double> power,
                              std::span<double> agreement) const {
  int pairs = 0;
  const double omega = gcc.bin_omega_rad_per_s();
  const int first_bin = gcc.band().front().first_bin;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairTdoa& tdoa = lags[static_cast<std::size_t>(p)];
    if (!(tdoa.variance_s2 > 0.0)) continue;
    ++pairs;
    const MicPairSpec& spec = gcc.pair_spec(p);
    const std::span<const double> magnitude = gcc.magnitudes(p);
    const std::span<const double> ri = units.real_row(spec.mic_i);
    const std::span<const double> ii = units.imag_row(spec.mic_i);
    const std::span<const double> rj = units.real_row(spec.mic_j);
    const std::span<const double> ij = units.imag_row(spec.mic_j);
    std::size_t index = 0;
    for (const BandRun& run : gcc.band()) {
      const auto bins = static_cast<std::size_t>(run.last_bin - run.first_bin + 1);
      const auto bin = static_cast<std::size_t>(run.first_bin - first_bin);
      simd::steered_agreement({bins,
                               static_cast<double>(run.first_bin),
                               omega,
                               tdoa.tdoa_s,
                               {ri.data() + index, ii.data() + index},
                               {rj.data() + index, ij.data() + index},
                               magnitude.data() + index,
                               keep.data() + index,
                               power.data() + bin,
                               agreement.data() + bin});
      index += bins;
    }
  }
  return pairs;
}

// Every source's ground reflection, found on its own bins (the others' dropped), divided out of
// the mics' phases; its TDOAs are then measured again and the units put back for the next.
void NodePipeline::Impl::remove_ground_echoes() {
  // Each state goes to the source it followed: pairs taken best-aligned first, so a stray look
  // cannot take the state of a drone that is still there (a new source gets a free state, which
  // then searches afresh: a jump).
  std::array<bool, kMaxSources> state_taken{};
  std::array<int, kMaxSources> state_of_source{};
  state_of_source.fill(-1);
  const auto states = static_cast<int>(ground_echoes.size());
  for (int round = 0; round < std::min(candidate_count, states); ++round) {
    int best_source = -1;
    int best_state = -1;
    double best_alignment = -2.0;
    for (int s = 0; s < candidate_count; ++s) {
      if (state_of_source[static_cast<std::size_t>(s)] >= 0) continue;
      const Eigen::Vector3d& direction =
          candidates[static_cast<std::size_t>(s)].solution.direction_site;
      for (int e = 0; e < states; ++e) {
        const double alignment = ground_echoes[static_cast<std::size_t>(e)].alignment(direction);
        if (!state_taken[static_cast<std::size_t>(e)] && alignment > best_alignment) {
          best_alignment = alignment;
          best_source = s;
          best_state = e;
        }
      }
    }
    state_taken[static_cast<std::size_t>(best_state)] = true;
    state_of_source[static_cast<std::size_t>(best_source)] = best_state;
  }
  for (int s = 0; s < candidate_count; ++s)
    if (const int e = state_of_source[static_cast<std::size_t>(s)]; e >= 0)
      remove_ground_echo(s, ground_echoes[static_cast<std::size_t>(e)]);
}

void NodePipeline::Impl::remove_ground_echo(int source, GroundEcho& echo) {
  const Eigen::Vector3d direction =
      candidates[static_cast<std::size_t>(source)].solution.direction_site;
  // The search reads this source's bins: the frame's, minus the other sources' (when there
  // are others: their bins found on the remade phasors).
  const bool others = candidate_count > 1;
  if (others && echo.search_due(direction)) only_bins_of(source, gcc.units());
  if (!echo.observe(gcc, direction, others ? std::as_const(gcc).bin_keep() : frame_mask)) return;
  candidates[static_cast<std::size_t>(source)].echo_removed =
      remeasure(source, echo.corrected(gcc.units(), direction), true);
}

// A source was measured with every other source's bins in its correlation (the first), or on a
// look made for another (SRP): measured again without the others' bins (their lobes no longer
// pull its peaks), near its own TDOAs.
bool NodePipeline::Impl::remeasure(int source, const GccPhat::UnitsView& units,
                                   bool near_known_lags, CombLines comb_permission) {
  // On its comb's lines alone a source's correlation is a correction of the one on all its
  // bins, not a new search: fewer bins leave neighbouring carrier lobes nearly as high, so the
  // peak is refined from the known lags only.
  near_known_lags = only_bins_of(source, units, true, comb_permission) || near_known_lags;
  if (!near_known_lags) gcc.correlate(false);
  Candidate& candidate = candidates[static_cast<std::size_t>(source)];
  std::array<PairTdoa, kMaxPairs> remeasured{};
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairTdoa& before = candidate.tdoas[static_cast<std::size_t>(p)];
    GccPeak peak;
    const bool found = near_known_lags ? gcc.refine_from(p, before.tdoa_s, peak)
                                       : gcc.refine(p, before.tdoa_s, peak);
    if (before.variance_s2 > 0.0 && found && peak.value > 0.0)
      remeasured[static_cast<std::size_t>(p)] = {peak.lag_s, gcc.tdoa_variance_for_peak(peak.value),
                                                 peak.value, peak.coherence};
  }
  const std::span<const PairTdoa> again(remeasured.data(), tdoas.size());
  const DoaSolution solution = solver.solve(again);
  if (!solution.accepted) return false;
  candidate.solution = solution;
  std::copy(again.begin(), again.end(), candidate.tdoas.begin());
  return true;
}

// Drops the bins a found source owns and correlates what is left (the frame's earlier
// correlation values, already used, are overwritten).
void NodePipeline::Impl::mask_source(std::span<const PairTdoa> source_tdoas, bool null_observes) {
  bin_mask.drop(gcc, source_tdoas);
  // Further looks in plain PHAT: the SNR weights favour the first source's bins, and SRP's
  // noise floor is calibrated on equal weights. Refined peaks only when the static null
  // observes this look (SRP refines where it asks, the same answers).
  gcc.correlate(null_observes, false);
  if (null_observes) null_observe();
}

// Replaces this frame's per-frame candidates by every tracked source's smoothed estimate for
// the frame output_delay_s() back.
void NodePipeline::Impl::smooth_candidates(double time_s) {
  for (int s = 0; s < candidate_count; ++s) {
    const Candidate& candidate = candidates[static_cast<std::size_t>(s)];
    observations[static_cast<std::size_t>(s)] = {
        candidate.solution.direction_site,
        std::span<const PairTdoa>(candidate.tdoas.data(), tdoas.size())};
  }
  const int estimate_count = source_tracks->update(
      time_s, std::span<const SourceObservation>(observations.data(), candidate_count), estimates);
  if (acoustic_due) {
    int count = 0;
    for (int slot = 0; slot < source_tracks->slot_count() && count < kMaxSources; ++slot) {
      const int observation = source_tracks->observation_of(slot);
      if (observation < 0) continue;
      acoustic_directions[static_cast<std::size_t>(count)] =
          candidates[static_cast<std::size_t>(observation)].solution.direction_site;
      acoustic_slots[static_cast<std::size_t>(count)] = slot;
      acoustic_generations[static_cast<std::size_t>(count)] = source_tracks->generation(slot);
      ++count;
    }
    measure_acoustics(count);
  }
  candidate_count = 0;
  for (int e = 0; e < estimate_count && candidate_count < params.max_sources; ++e) {
    const SourceEstimate& estimate = estimates[static_cast<std::size_t>(e)];
    const std::span<const PairTdoa> smoothed(estimate.tdoas.data(), tdoas.size());
    Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
    candidate.solution = solver.solve(smoothed);
    if (!candidate.solution.accepted) continue;
    // Two tracks that followed one source: the stronger speaks for it.
    if (already_found(candidate.solution.direction_site)) continue;
    std::copy(smoothed.begin(), smoothed.end(), candidate.tdoas.begin());
    candidate.coherence = mean_coherence(smoothed);
    candidate.time_offset_s = source_tracks->output_delay_s();
    candidate.slot = estimate.track;
    ++candidate_count;
  }
}

void NodePipeline::Impl::measure_acoustics(int count) {
  const auto n = static_cast<std::size_t>(count);
  acoustic->analyse(fft, std::span<const Eigen::Vector3d>(acoustic_directions.data(), n),
                    std::span<const int>(acoustic_slots.data(), n),
                    std::span<const std::uint32_t>(acoustic_generations.data(), n));
}

bool NodePipeline::Impl::was_detecting(double time_s) const {
  const double half_hop_s = 0.5 * hop / sample_rate_hz;
  for (const FrameDetection& frame : recent_detections)
    if (std::abs(frame.time_s - time_s) < half_hop_s) return frame.detecting;
  return false;
}

}  // namespace dronetrack::doa
