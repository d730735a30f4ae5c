#pragma once
// The fusion node's core: DOAs from all arrays in, 3-D tracks out. Plain C++ on Eigen; the
// DDS fusion process and the in-process replay both drive it through this interface.
#include <cstdint>
#include <memory>
#include <vector>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"
#include "fusion/doa_admission.hpp"
#include "fusion/fusion_params.hpp"
#include "fusion/track_report.hpp"

namespace dronetrack::fusion {

struct FusionCounters {
  std::int64_t accepted = 0;
  std::int64_t rejected_non_finite = 0;
  std::int64_t rejected_unknown_array = 0;
  std::int64_t rejected_too_late = 0;
  std::int64_t rejected_duplicate = 0;
  std::int64_t rejected_bad_direction = 0;
  std::int64_t gated_out = 0;  // valid DOAs that matched no track and started none
  std::int64_t tracks_started = 0;
  std::int64_t tracks_deleted = 0;
  std::int64_t tracks_confirmed = 0;
  std::int64_t ghosts_rejected = 0;        // triangulated candidates another array contradicted
  std::int64_t below_ground_rejected = 0;  // candidate points under the ground (echo images)
  std::int64_t filter_repairs = 0;         // covariances repaired (eigenvalue clamp)
  std::int64_t filter_failures = 0;        // updates refused as non-finite/unrepairable
  std::int64_t manoeuvres_followed = 0;    // tracks widened by the manoeuvre onset test
  std::int64_t duplicates_pruned = 0;      // confirmed tracks deleted as duplicates along a ray
};

class FusionEngine {
 public:
  // `params` as checked by config::check_fusion_params (the site config's parse, or
  // config::validate for hand-made params): their bounds live there alone, and the engine trusts
  // them. Throws std::invalid_argument when `arrays` is not 2 to 64 arrays (1 with
  // single_array_start): the tracker's per-array records are fixed at 64.
  FusionEngine(const FusionParams& params, std::vector<doa::ArrayGeometry> arrays,
               double speed_of_sound_mps);
  ~FusionEngine();
  FusionEngine(FusionEngine&&) noexcept;
  FusionEngine& operator=(FusionEngine&&) noexcept;

  // Validates and queues a DOA (any order within the reorder window). Never throws.
  DoaVerdict add(const doa::DoaMeasurement& measurement);
  // The checks of add() that need no tracker state (finite, known array, unit direction,
  // positive definite covariance), counted the same way, without queueing the DOA: for a run
  // whose outputs need no tracks (a DOA-only replay), so the tracker is not run for nothing.
  // Never throws.
  DoaVerdict admit(const doa::DoaMeasurement& measurement);
  // Feeds every queued DOA older than time_s - reorder_window_s to the tracker, oldest first.
  void advance_to(double time_s);
  // Live tracks predicted to time_s (which should not precede the last advance_to).
  void tracks_at(double time_s, std::vector<TrackReport>& out) const;
  const FusionCounters& counters() const;
  const std::vector<doa::ArrayGeometry>& arrays() const;
  // Swaps the mirror check (fusion/array_mirror_check.hpp) named since the last call, appended
  // to `out` (each once, when it is named).
  void take_mirror_events(std::vector<MirrorSwapEvent>& out);
  // Array `array`'s (site order) mirror check standing (the fusion's diagnostics).
  const MirrorCheckStatus& mirror_status(std::size_t array) const;
  // The outlier mixture's e for array `array`'s DOAs now: its estimate when
  // adaptive_outlier_probability, else outlier_probability (0 under another likelihood).
  double outlier_share(std::size_t array) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dronetrack::fusion
