#pragma once
// Accuracy of NodePipeline on simulated scenes (sim/ in-memory API), against the simulator's
// truth directions at the DOA times. A frame counts as "audible" for a drone at an array when
// that drone's in-band SNR (its own rendering against the background: sensor, wind and ambient
// noise = full scene minus every source rendered alone; interferers are not background) is at least
// `audible_snr_db`; a drone is "found" in a frame when a DOA of that frame lies within
// `found_within_deg` of its true direction, and its error is that DOA's angle to the truth.
#include <string>
#include <vector>

#include "doa/doa_params.hpp"
#include "sim/render.hpp"
#include "sim/scenario.hpp"

namespace dronetrack::doa::testing {

struct RenderedScenario {
  sim::Scenario scenario;
  sim::Truth truth;
  std::vector<sim::RenderedArray> full;                      // per array
  std::vector<std::vector<sim::RenderedArray>> drone_alone;  // per drone, per array (no noise)
  std::vector<sim::RenderedArray> interferers_alone;         // per array, all interferers
};
RenderedScenario render_for_evaluation(const sim::Scenario& scenario);

// One analysis frame of a drone at an array: its in-band SNR against the background (the
// `audible_snr_db` rule), against everything else (background, interferers, other drones) over
// the whole band, and against everything else on its own comb bins (the band bins where the
// drone alone stands >= 10 dB above its own median bin); the angle of the frame's nearest DOA.
// Why a comb-audible frame has no DOA within found_within_deg of the drone (--breakdown), the
// first that applies in pipeline order (doa/node_trace.hpp's FrameTrace of the frame).
enum class MissCause : int {
  found = 0,        // not missed
  not_sharp,        // the first look's peaks too flat: no source looked for
  gate_closed,      // sources found, the detection gate closed: nothing published
  null_dropped,     // the static null dropped most of the drone's comb power
  regression,       // a candidate of the frame within reach, the smoothed DOA not
  refused_pairs,    // a look within reach, refused by the LS solver: too few pairs
  refused_norm,     // ... its lags fit no plane wave (norm gate)
  refused_chi2,     // ... residual gate
  duplicate,        // ... taken for a source the frame already had
  below_horizon,    // ... under min_elevation_deg
  remeasure_moved,  // a look within reach kept, its re-measure (echo, own comb) moved it off
  off_target,       // the nearest look or candidate 3-20 deg off (fringe, bias, pull)
  capacity,         // max_sources spent on other sources first
  owned_by_others,  // most of the drone's comb power dropped with other sources' bins
  under_floor,      // nothing left cleared the SRP floor
  looks_spent,      // the free looks ran out on refused or duplicate looks
  other,
  count
};
const char* miss_cause_name(MissCause cause);

struct FrameAudibility {
  double background_snr_db = -100.0;
  double band_snr_db = -100.0;
  double comb_snr_db = -100.0;
  double error_deg = 180.0;            // nearest DOA of the frame to the truth (180: none)
  double elevation_error_deg = 0.0;    // that DOA's elevation minus the truth's
  MissCause cause = MissCause::found;  // breakdown only
  double off_deg = 0.0;                // off_target: the nearest look's or candidate's angle
  double off_elevation_deg = 0.0;      // ... its elevation minus the truth's
  // ... what it was: a candidate after the re-measures (-1), or a look (its LookKind), and
  // whether it was kept.
  int off_kind = -1;
  bool off_kept = true;
  double truth_elevation_deg = 0.0;
  // under_floor: the free search's end (effective bins kept, the best power left over the floor)
  // and the comb look's (its line bins, 0: no look; its best power over its floor).
  int kept_bins = 0;
  double floor_ratio = 0.0;
  int comb_line_bins = 0;
  double comb_floor_ratio = 0.0;
};

struct DroneAtArray {
  std::string drone_id;
  std::string array_id;
  int audible_frames = 0;
  int found_frames = 0;
  std::vector<double> errors_deg;       // one per found frame
  double max_snr_db = -100.0;           // best in-band SNR over the frames
  std::vector<FrameAudibility> frames;  // every frame, audible or not
  double median_deg() const;
  double p90_deg() const;
  double coverage() const {
    return audible_frames > 0 ? double(found_frames) / audible_frames : 0.0;
  }
};

struct SceneResult {
  std::vector<DroneAtArray> cells;  // drone-major
  int doas = 0;
  int stray_doas = 0;  // DOAs within found_within_deg of no source (drone or interferer)
  double seconds_processed = 0.0;
  double seconds_cpu = 0.0;
};

struct EvaluationSettings {
  double audible_snr_db = 6.0;
  double found_within_deg = 3.0;
  // Fill FrameAudibility::band_snr_db / comb_snr_db (one more spectrum per drone and array:
  // off for the tests, which use the background rule only).
  bool audibility = false;
  // Trace every frame (NodePipeline::set_frame_trace) and give each missed frame a MissCause
  // (needs audibility: the drone's comb bins).
  bool breakdown = false;
  // Print every frame of one array whose centre lies in [frames_from_s, frames_to_s] as the
  // trace saw it: each look (kind, outcome, direction), why the search stopped, the comb look's
  // line bins, the candidates, and every source's true direction (empty: none).
  std::string frames_array;
  double frames_from_s = 0.0;
  double frames_to_s = -1.0;
};

SceneResult evaluate(const RenderedScenario& rendered, const DoaParams& params,
                     const EvaluationSettings& settings = {});

// Per drone and array: frames heard by each audibility rule at 0 and 6 dB, and the DOA coverage
// over them ("| scene | array | drone | all | background 0/6 | band 0/6 | comb 0/6 |" rows), then
// the median signed elevation error of the found frames.
std::string format_audibility_rows(const std::string& scene, const SceneResult& result,
                                   double found_within_deg);

// Per drone and array, the frames whose comb stands >= 0 dB over everything else and have no
// DOA within found_within_deg, counted by MissCause, and the off_target offsets' spread.
std::string format_breakdown_rows(const std::string& scene, const SceneResult& result,
                                  double found_within_deg);

// "| scene | tracker | array | drone | median | p90 | coverage |" rows.
std::string format_rows(const std::string& scene, const std::string& tracker,
                        const SceneResult& result);

}  // namespace dronetrack::doa::testing
