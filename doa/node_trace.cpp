// NodePipeline's frame trace (set_frame_trace): what the source stages did, for tools that
// explain a missed source. Every call returns at once without a sink.
#include "doa/node_pipeline_impl.hpp"

namespace dronetrack::doa {

void NodePipeline::Impl::trace_begin(double time_s) {
  if (!trace_sink) return;
  trace.time_s = time_s;
  trace.sharp = false;
  trace.detecting = false;
  trace.look_count = 0;
  trace.search_end = SearchEnd::not_run;
  trace.search_end_floor = 0.0;
  trace.search_end_best_power = 0.0;
  trace.search_end_kept_bins = 0;
  trace.comb_line_bins = 0;
  trace.comb_look_floor = 0.0;
  trace.comb_look_best_power = 0.0;
  trace.candidate_count = 0;
  std::fill(trace.kept_after_null.begin(), trace.kept_after_null.end(), std::uint8_t{1});
  std::fill(trace.kept_at_search_end.begin(), trace.kept_at_search_end.end(), std::uint8_t{1});
}

void NodePipeline::Impl::trace_look(LookKind kind, const DoaSolution& solution, bool duplicate,
                                    const Eigen::Vector3d* look_direction_array) {
  if (!trace_sink || trace.look_count >= FrameTrace::kMaxLooks) return;
  LookTrace& look = trace.looks[static_cast<std::size_t>(trace.look_count++)];
  look.kind = kind;
  look.direction_site = solution.accepted || look_direction_array == nullptr
                            ? solution.direction_site
                            : Eigen::Vector3d(solver.array_to_site() * *look_direction_array);
  if (!solution.accepted) {
    // The solver's own gates, in its order.
    if (solution.pairs_used < 3)
      look.outcome = LookOutcome::refused_pairs;
    else if (std::abs(solution.norm - 1.0) > params.max_norm_error)
      look.outcome = LookOutcome::refused_norm;
    else
      look.outcome = LookOutcome::refused_chi2;
  } else if (duplicate) {
    look.outcome = LookOutcome::duplicate;
  } else if (solver.rank() >= 3 && solution.direction_site.z() < min_elevation_sine) {
    look.outcome = LookOutcome::below_horizon;
  } else {
    look.outcome = LookOutcome::kept;
  }
  // The primary's look is the first: the mask it leaves (static null, a ground primary's bins
  // dropped) is what every further look starts from.
  if (kind == LookKind::primary) {
    const std::span<const std::uint8_t> keep = std::as_const(gcc).bin_keep();
    std::copy(keep.begin(), keep.end(), trace.kept_after_null.begin());
  }
}

void NodePipeline::Impl::trace_added(LookKind kind, int first_candidate) {
  if (!trace_sink) return;
  for (int s = first_candidate; s < candidate_count; ++s)
    trace_look(kind, candidates[static_cast<std::size_t>(s)].solution, false);
}

void NodePipeline::Impl::trace_search_end(bool under_floor) {
  if (!trace_sink) return;
  trace.search_end = under_floor                             ? SearchEnd::under_floor
                     : candidate_count >= params.max_sources ? SearchEnd::capacity
                                                             : SearchEnd::looks_spent;
  const std::span<const std::uint8_t> keep = std::as_const(gcc).bin_keep();
  std::copy(keep.begin(), keep.end(), trace.kept_at_search_end.begin());
  if (!under_floor) return;
  trace.search_end_floor = kept_bins_floor();
  trace.search_end_kept_bins = gcc.kept_bin_count();
  SrpPeak peak;
  trace.search_end_best_power = srp->strongest(peak) ? peak.power : 0.0;
}

void NodePipeline::Impl::trace_comb_look(int line_bins, double floor) {
  if (!trace_sink) return;
  trace.comb_line_bins = line_bins;
  trace.comb_look_floor = floor;
  SrpPeak peak;
  trace.comb_look_best_power = srp->strongest(peak) ? peak.power : 0.0;
}

void NodePipeline::Impl::trace_candidates() {
  if (!trace_sink) return;
  trace.candidate_count = std::min(candidate_count, FrameTrace::kMaxCandidates);
  for (int s = 0; s < trace.candidate_count; ++s)
    trace.candidates[static_cast<std::size_t>(s)] =
        candidates[static_cast<std::size_t>(s)].solution.direction_site;
}

void NodePipeline::Impl::trace_end(bool sharp, bool detecting) {
  if (!trace_sink) return;
  trace.sharp = sharp;
  trace.detecting = detecting;
  trace_sink->frame(trace);
}

}  // namespace dronetrack::doa
