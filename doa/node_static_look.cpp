// NodePipeline's static look (stage 7a): a hovering source under louder moving ones, found on the
// frames' averaged phasors, held and followed while it stays where it was.
#include "doa/node_pipeline_impl.hpp"

namespace dronetrack::doa {

// After the frame's own looks, the static look (StaticSourceLook): the source it holds measured
// again near its held direction, or (when due, or that failed) a search on the frames' averaged
// phasors with every found source's bins dropped, its peak measured on the frame's own phasors.
// It adds a source only where the own looks found none within own_look_memory_s (a direction a
// found source explains adds nothing: their source track bridges their gaps) and only when the
// direction is static (StaticSourceLook::held: a moving source's smeared average puts its peak
// elsewhere from look to look).
void NodePipeline::Impl::find_static_source() {
  for (int s = 0; s < candidate_count; ++s)
    found_directions[static_cast<std::size_t>(s)] =
        candidates[static_cast<std::size_t>(s)].solution.direction_site;
  static_look->note_found(
      frame_time_s, std::span<const Eigen::Vector3d>(found_directions.data(),
                                                     static_cast<std::size_t>(candidate_count)));
  // Static means static in the array's frame, which turns and moves with a moving array: a
  // source riding along (the vehicle's own engine) would be held, one standing still would not.
  if (!array_still()) {
    static_look->reset();
    return;
  }
  if (candidate_count >= params.max_sources) return;
  // The follow and the search leave other phasors in gcc (a re-measure's, the average's): no
  // later stage reads them, each remakes its own from the units under the mask it wants (the
  // ground echoes, the static null's own look), so they are not put back.
  if (static_look->holding() && follow_static_source()) return;
  if (static_look->search_due()) search_static_source();
}

// The held source measured on the frame's own phasors (the other sources' bins dropped) from
// its held direction's lags: a hovering drone moves a fraction of a grid step between frames,
// so no search is needed, only the re-measure every added source gets anyway.
bool NodePipeline::Impl::follow_static_source() {
  const Eigen::Vector3d held = static_look->held_direction();
  if (static_look->explained(frame_time_s, held, separation_cosine)) {
    static_look->lose();  // the own looks follow it now
    return false;
  }
  const int index = candidate_count;
  Candidate& candidate = candidates[static_cast<std::size_t>(index)];
  const Eigen::Vector3d held_array = solver.array_to_site().transpose() * held;
  // Any positive variance: remeasure() measures the pairs that have one.
  for (std::size_t p = 0; p < tdoas.size(); ++p)
    candidate.tdoas[p] = {solver.tdoa_for_direction(static_cast<int>(p), held_array), 1.0, 0.0,
                          0.0};
  ++candidate_count;
  bool kept = remeasure(index, gcc.units(), false, CombLines::not_allowed);
  for (int s = 0; kept && s < index; ++s)
    kept = candidate.solution.direction_site.dot(
               candidates[static_cast<std::size_t>(s)].solution.direction_site) < separation_cosine;
  if (kept &&
      static_look->follow(frame_time_s, candidate.solution.direction_site, separation_cosine)) {
    candidate.coherence =
        mean_coherence(std::span<const PairTdoa>(candidate.tdoas.data(), tdoas.size()));
    candidate.time_offset_s = 0.0;
    ++diagnostics.static_look_sources;
    return true;
  }
  static_look->lose();
  --candidate_count;
  return false;
}

// Up to max_looks SRP looks on the averaged phasors: a look that lands on a direction the own
// looks explain, or that is not static, has its lobe taken out before the next.
bool NodePipeline::Impl::search_static_source() {
  // The found sources' bins dropped as the average is loaded (one pass), else one by one.
  BinOwners owners;
  bool fused = true;
  for (int s = 0; s < candidate_count && fused; ++s)
    fused = bin_mask.add_owner(
        owners, {candidates[static_cast<std::size_t>(s)].tdoas.data(), tdoas.size()});
  if (fused) static_look->load_average(gcc, frame_mask, owners);
  if (!fused) static_look->load_average(gcc, frame_mask);
  if (!fused) drop_candidates(0, candidate_count);
  gcc.correlate(false);
  srp->begin_frame(gcc);
  const double floor = kept_bins_floor();
  Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
  const std::span<PairTdoa> candidate_tdoas(candidate.tdoas.data(), tdoas.size());
  for (int look = 0; look < params.static_look.max_looks; ++look) {
    SrpPeak peak;
    if (!srp->strongest(peak, floor)) return false;
    srp->tdoas_near(gcc, peak.direction_array, candidate_tdoas);
    candidate.solution = solver.solve(candidate_tdoas);
    // Only a direction no source the own looks found lately explains is remembered: a source
    // they follow (static, or a drone flying radially) must not make a static history of its own.
    const Eigen::Vector3d& direction = candidate.solution.direction_site;
    if (candidate.solution.accepted &&
        !static_look->explained(frame_time_s, direction, separation_cosine) &&
        static_look->held(frame_time_s, direction))
      return add_static_source(direction);
    srp->subtract_direction(gcc, peak.direction_array);
  }
  return false;
}

bool NodePipeline::Impl::add_static_source(const Eigen::Vector3d& look_direction_site) {
  const Eigen::Vector3d look = look_direction_site;  // the candidate's is measured again below
  Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
  candidate.coherence =
      mean_coherence(std::span<const PairTdoa>(candidate.tdoas.data(), tdoas.size()));
  candidate.time_offset_s = 0.0;
  const int index = candidate_count++;
  // Measured again on the frame's own phasors, the other sources' bins dropped: the frame's
  // measurement may have moved it onto a found source.
  bool kept = remeasure(index, gcc.units(), false, CombLines::not_allowed);
  for (int s = 0; kept && s < index; ++s)
    kept = candidate.solution.direction_site.dot(
               candidates[static_cast<std::size_t>(s)].solution.direction_site) < separation_cosine;
  if (kept) {
    // Held at the average's direction: steadier than one frame's measurement.
    static_look->hold(look);
    ++diagnostics.static_look_sources;
    return true;
  }
  --candidate_count;
  return false;
}

// Still over the static look's hold window (2 hold_s): turned less than half max_drift_deg and
// moved less than what turns a source kNearestStaticRange_m away by as much. No pose track: a
// fixed array.
bool NodePipeline::Impl::array_still() const {
  if (pose_track.empty()) return true;
  // The hovering drones the look is for are this far or farther (issue 14's hovers at 30 m up).
  constexpr double kNearestStaticRange_m = 30.0;
  const double tolerance_rad = 0.5 * params.static_look.max_drift_deg * std::numbers::pi / 180.0;
  const double now_s = frame_time_s - geometry.clock_offset_s;
  const std::optional<PoseStamp> now = pose_track.stamp(now_s, geometry);
  if (!now) return false;
  const double window_s = 2.0 * params.static_look.hold_s;
  // Every pose line of the window and its start (a platform that went and came back moved).
  auto still_at = [&](double time_s) {
    const std::optional<PoseStamp> then = pose_track.stamp(time_s, geometry);
    return then && then->array_to_site.angularDistance(now->array_to_site) <= tolerance_rad &&
           (then->centre_m - now->centre_m).norm() <= kNearestStaticRange_m * tolerance_rad;
  };
  if (!still_at(now_s - window_s)) return false;
  const std::vector<PoseSample>& samples = pose_track.samples();
  auto sample =
      std::upper_bound(samples.begin(), samples.end(), now_s - window_s,
                       [](double time_s, const PoseSample& line) { return time_s < line.time_s; });
  for (; sample != samples.end() && sample->time_s < now_s; ++sample)
    if (!still_at(sample->time_s)) return false;
  return true;
}

void NodePipeline::Impl::keep_frame_mask() {
  const std::span<const std::uint8_t> keep = std::as_const(gcc).bin_keep();
  std::copy(keep.begin(), keep.end(), frame_mask.begin());
}

}  // namespace dronetrack::doa
