#pragma once
// What a frame's source stages did, for tools that explain a missed source against the truth
// (tests/doa/scene_eval's --breakdown): every look in pipeline order with its outcome, why the
// free search stopped, the frame's candidates before the per-source regression, and the band
// bins kept after the static null and at the search's end. Off unless a sink is set; filled
// in place (sized once, at NodePipeline::set_frame_trace), so tracing allocates nothing per frame.
#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace dronetrack::doa {

// comb: the look on the kept bins of a harmonic comb, after the free search stopped under the
// floor (doa.comb_look).
enum class LookKind : std::uint8_t { primary, followed, free, static_look, comb };
enum class LookOutcome : std::uint8_t {
  kept,
  refused_pairs,  // the LS solver had too few pairs with a peak
  refused_norm,   // ||A^-1 b| - 1| over max_norm_error: the lags fit no plane wave
  refused_chi2,   // the fit's residual over max_chi2_per_dof
  duplicate,      // within srp_min_separation_deg of a source the frame already has
  below_horizon,  // under min_elevation_deg (a ground source or a drone's ground image)
};
enum class SearchEnd : std::uint8_t {
  not_run,      // not sharp, no SRP, or the primary was the only look
  capacity,     // max_sources found
  under_floor,  // no direction of what was left cleared the SRP noise floor
  looks_spent,  // every free look made (max_sources + 2, at most kMaxFreeLooks), the last ones
                // refused or duplicates
};

// Names for printing a trace. A switch with no default: -Wswitch names an enumerator added
// without one.
constexpr const char* name(LookKind kind) {
  switch (kind) {
    case LookKind::primary:
      return "primary";
    case LookKind::followed:
      return "followed";
    case LookKind::free:
      return "free";
    case LookKind::static_look:
      return "static";
    case LookKind::comb:
      return "comb";
  }
  return "?";
}
constexpr const char* name(LookOutcome outcome) {
  switch (outcome) {
    case LookOutcome::kept:
      return "kept";
    case LookOutcome::refused_pairs:
      return "refused pairs";
    case LookOutcome::refused_norm:
      return "refused norm";
    case LookOutcome::refused_chi2:
      return "refused chi2";
    case LookOutcome::duplicate:
      return "duplicate";
    case LookOutcome::below_horizon:
      return "below horizon";
  }
  return "?";
}
constexpr const char* name(SearchEnd end) {
  switch (end) {
    case SearchEnd::not_run:
      return "not run";
    case SearchEnd::capacity:
      return "capacity";
    case SearchEnd::under_floor:
      return "under floor";
    case SearchEnd::looks_spent:
      return "looks spent";
  }
  return "?";
}

struct LookTrace {
  LookKind kind = LookKind::primary;
  LookOutcome outcome = LookOutcome::kept;
  Eigen::Vector3d direction_site = Eigen::Vector3d::UnitX();  // the solution's, or the look's
};

struct FrameTrace {
  static constexpr int kMaxLooks = 24;
  static constexpr int kMaxCandidates = 8;
  double time_s = 0.0;  // the frame's centre (a DOA published for it carries this time)
  bool sharp = false;   // the first look's peaks were sharp enough to look for sources
  bool detecting = false;
  int look_count = 0;
  std::array<LookTrace, kMaxLooks> looks{};
  SearchEnd search_end = SearchEnd::not_run;
  // When the free search stopped under the floor: the floor for the bins then kept, the highest
  // SRP power left (searched for the trace only), and the effective count of bins kept.
  double search_end_floor = 0.0;
  double search_end_best_power = 0.0;
  int search_end_kept_bins = 0;
  // The comb look after it (doa.comb_look; 0 line bins: no comb, no look): the same three.
  int comb_line_bins = 0;
  double comb_look_floor = 0.0;
  double comb_look_best_power = 0.0;
  // After the ground echoes' re-measures, before the per-source regression.
  int candidate_count = 0;
  std::array<Eigen::Vector3d, kMaxCandidates> candidates{};
  // Band bins (the band's order), 1 = kept: after the static null (what the first look saw);
  // when the free search stopped (the bins of every source found so far dropped).
  std::vector<std::uint8_t> kept_after_null;
  std::vector<std::uint8_t> kept_at_search_end;
};

class FrameTraceSink {
 public:
  virtual ~FrameTraceSink() = default;
  // Called once per analysed frame, after its sources are found and before publishing.
  virtual void frame(const FrameTrace& trace) = 0;
};

}  // namespace dronetrack::doa
