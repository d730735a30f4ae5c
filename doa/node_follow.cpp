// NodePipeline's followed sources (follow_source_tracks): before the free SRP looks of a frame,
// each source the node already tracks and the frame has not found yet is measured from its
// track's lags on the bins left.
#include "doa/node_pipeline_impl.hpp"

namespace dronetrack::doa {

// A weaker source whose own bins are only its rotor's lines correlates as fringes one carrier
// period apart under a wide envelope (its lines span ~2 kHz around ~2.5 kHz), the neighbouring
// fringes nearly as high as the peak. A free search takes whichever is highest this frame, and
// its own ground echo lifts the fringe below (docs/doa.md, "D2 at N1"): the mixed site's hovering
// drone came out 11 deg low in a third of N1's frames, each time a new source. The source
// tracks know which fringe the source was on a hop ago; each unexplained track heard a hop ago
// (SourceTracks::followable: after a gap the gate reaches the next fringe) is measured
// from its lags (every pair's nearest correlation maximum, solved), kept when the solution stays
// within the track's association gate and its steered power clears the SRP look's noise floor,
// strongest first, each taking its bins before the next.
void NodePipeline::Impl::follow_tracked_sources() {
  std::array<bool, kMaxSources> tried{};
  const int slots = std::min(source_tracks->slot_count(), kMaxSources);
  const auto pairs = tdoas.size();
  while (candidate_count < params.max_sources) {
    const double floor = kept_bins_floor();
    int best_slot = -1;
    double best_power = floor;
    for (int slot = 0; slot < slots; ++slot) {
      if (tried[static_cast<std::size_t>(slot)] || !source_tracks->followable(slot, frame_time_s))
        continue;
      const Eigen::Vector3d& track_direction = source_tracks->direction_site(slot);
      const std::span<PairTdoa> measured(follow_tdoas.data(), pairs);
      double power = 0.0;
      const bool kept =
          !already_found(track_direction) &&
          measure_near(track_direction, measured, follow_solution, power) &&
          follow_solution.direction_site.dot(track_direction) >=
              std::cos(source_tracks->gate_deg(slot, frame_time_s) * std::numbers::pi / 180.0);
      if (!kept) {
        tried[static_cast<std::size_t>(slot)] = true;
        continue;
      }
      if (power <= best_power) continue;
      best_power = power;
      best_slot = slot;
      std::copy(follow_tdoas.begin(), follow_tdoas.begin() + static_cast<std::ptrdiff_t>(pairs),
                best_follow_tdoas.begin());
      best_follow_solution = follow_solution;
    }
    if (best_slot < 0) return;
    tried[static_cast<std::size_t>(best_slot)] = true;
    if (already_found(best_follow_solution.direction_site) || below_horizon(best_follow_solution))
      continue;
    if (fringe_of_found(std::span<const PairTdoa>(best_follow_tdoas.data(), pairs),
                        best_follow_solution.direction_site)) {
      ++diagnostics.fringes_not_followed;
      continue;
    }
    Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
    candidate.solution = best_follow_solution;
    std::copy(best_follow_tdoas.begin(),
              best_follow_tdoas.begin() + static_cast<std::ptrdiff_t>(pairs),
              candidate.tdoas.begin());
    accept_candidate();
    ++diagnostics.followed_sources;
    if (candidate_count < params.max_sources)
      mask_source(std::span<const PairTdoa>(candidate.tdoas.data(), pairs));
  }
}

// The louder source's lines stay in the frame's bins, and a track that once took one of its
// carrier fringes (a free look's or a stray's) measures that fringe again every hop: the
// mixed site's N4 published DOAs 4-6 deg off D1 carrying a 151 Hz comb of 4-5 lines (D1's is
// 148 Hz with 18) and crossed them with another array's rays into a ghost said `drone`. On the
// frame's bins (before any source's are dropped) the steered spectrum of a direction on the
// louder source's fringe holds the lines near its carrier in phase and no comb of its own;
// a second drone there shows its own spacing (docs/doa.md, stage 7d).
bool NodePipeline::Impl::fringe_of_found(std::span<const PairTdoa> followed_tdoas,
                                         const Eigen::Vector3d& follow_direction_site) {
  if (!own_comb) return false;
  const Eigen::Matrix3d site_to_array = solver.array_to_site().transpose();
  std::array<double, kMaxPairs> follow_lags{};
  const auto pairs = static_cast<std::size_t>(gcc.pair_count());
  const Eigen::Vector3d follow_array = site_to_array * follow_direction_site;
  for (std::size_t p = 0; p < pairs; ++p)
    follow_lags[p] = solver.tdoa_for_direction(static_cast<int>(p), follow_array);
  HarmonicComb follow_comb;
  bool follow_comb_measured = false;
  for (int s = 0; s < candidate_count; ++s) {
    const FoundComb& found = found_comb(s);
    if (!found.shows_comb) continue;
    if (!within_one_carrier_fringe(std::span<const double>(found.lags_s.data(), pairs),
                                   std::span<const double>(follow_lags.data(), pairs),
                                   found.carrier_hz))
      continue;
    if (!follow_comb_measured) {
      int used_pairs = 0;
      follow_comb = steered_comb(followed_tdoas, gcc.units(), frame_mask, used_pairs);
      follow_comb.harmonic_count = own_comb->mark_lines(follow_comb, comb_lines);
      follow_comb_measured = true;
    }
    if (comb_is_the_sources(found.comb, follow_comb, node_detail::kMinOwnCombLines,
                            0.5 * own_comb->bin_hz()))
      return true;
  }
  return false;
}

// A found source's steered comb on the frame's bins, its carrier and its plane-wave lags, made
// once a frame, when a follow is first judged against it. A follow kept after that takes its
// bins from the units, so a later follow is judged against the source's comb as it stood before
// (not bit-identical to making it per follow: perimeter draw 303's DOAs differ from the first
// frame with two follows; docs/doa.md "Session 17 (branch `fringe2`)").
const NodePipeline::Impl::FoundComb& NodePipeline::Impl::found_comb(int source) {
  FoundComb& found = found_combs[static_cast<std::size_t>(source)];
  if (found.made) return found;
  found.made = true;
  const Candidate& candidate = candidates[static_cast<std::size_t>(source)];
  const auto pairs = static_cast<std::size_t>(gcc.pair_count());
  int used_pairs = 0;
  found.comb = steered_comb(std::span<const PairTdoa>(candidate.tdoas.data(), pairs), gcc.units(),
                            frame_mask, used_pairs);
  found.shows_comb = own_comb->mark_lines(found.comb, comb_lines) >= node_detail::kMinOwnCombLines;
  if (!found.shows_comb) return found;
  found.carrier_hz = comb_carrier_hz(comb_power, comb_lines, comb_first_bin, own_comb->bin_hz());
  const Eigen::Vector3d found_array =
      solver.array_to_site().transpose() * candidate.solution.direction_site;
  for (std::size_t p = 0; p < pairs; ++p)
    found.lags_s[p] = solver.tdoa_for_direction(static_cast<int>(p), found_array);
  return found;
}

// Every pair's correlation maximum nearest the lags of a direction (the fringe the source was
// on), solved; its power is the mean over pairs of the correlations at the solution's lags.
bool NodePipeline::Impl::measure_near(const Eigen::Vector3d& direction_site,
                                      std::span<PairTdoa> out, DoaSolution& solution,
                                      double& power) const {
  const Eigen::Vector3d direction_array = solver.array_to_site().transpose() * direction_site;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    GccPeak peak;
    const bool found = gcc.refine(p, solver.tdoa_for_direction(p, direction_array), peak);
    out[static_cast<std::size_t>(p)] =
        found && peak.value > 0.0 ? PairTdoa{peak.lag_s, gcc.tdoa_variance_for_peak(peak.value),
                                             peak.value, peak.coherence}
                                  : PairTdoa{};
  }
  solution = solver.solve(out);
  if (!solution.accepted) return false;
  const Eigen::Vector3d solved_array = solver.array_to_site().transpose() * solution.direction_site;
  double sum = 0.0;
  for (int p = 0; p < gcc.pair_count(); ++p)
    sum += gcc.grid_value(p, solver.tdoa_for_direction(p, solved_array));
  power = sum / gcc.pair_count();
  return true;
}

}  // namespace dronetrack::doa
