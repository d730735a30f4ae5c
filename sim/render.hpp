#pragma once
// The simulator's in-memory API: render what each array hears, the ground truth, and the files
// `dronetrack replay` / `dronetrack eval` read. Other modules' tests synthesise scenes with this
// directly (no files):
//   sim::Scenario scenario = sim::parse_scenario(json, ".");
//   sim::RenderedArray a1 = sim::render_array(scenario, 0);
#include <atomic>
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "sim/scenario.hpp"

namespace dronetrack::sim {

struct RenderedArray {
  std::string id;
  double sample_rate_hz = 48000.0;
  std::size_t channels = 0;
  std::vector<float> samples;  // interleaved, channel i = mic i (or its channel_map entry)
  std::size_t frames() const { return channels ? samples.size() / channels : 0; }
};

// What one array records, in full-scale units (1.0 = scenario.full_scale_db_spl), not scaled
// against clipping (render_scene does that for the whole scene). Frames stop at the array's
// recording_end_s if given.
RenderedArray render_array(const Scenario& scenario, std::size_t array_index);

struct RenderedScene {
  std::vector<RenderedArray> arrays;
  double peak_before_scaling = 0.0;  // largest |sample| over all arrays
  double scale = 1.0;                // common factor applied to every array (< 1 if it clipped)
  bool interrupted = false;          // `stop` was set: arrays holds only those rendered before
};
// Every array; if any sample would reach full scale, all arrays are scaled by one common factor
// to a peak of 0.9 (so inter-array levels stay true) and a warning is logged.
// `stop`, when given and set, ends the rendering between arrays (RenderedScene::interrupted).
RenderedScene render_scene(const Scenario& scenario, const std::atomic<bool>* stop = nullptr);

struct SourceTruth {
  std::string id;
  bool is_drone = true;
  std::string source_class = "drone";  // the scenario source's class
  std::vector<double> t_s;
  std::vector<Eigen::Vector3d> position_m;
  std::vector<Eigen::Vector3d> velocity_mps;
  // Per array (site order): unit vector from the array's acoustic centre toward where the source
  // was when the sound arriving at t left it.
  std::vector<std::vector<Eigen::Vector3d>> direction;
};

struct Truth {
  double rate_hz = 100.0;
  std::vector<std::string> array_ids;
  std::vector<SourceTruth> sources;  // drones and interferers, scenario order
  // SPEC 3.2b: {"sources": [drones...], "interferers": [...], ...}.
  nlohmann::json to_json(const Scenario& scenario) const;
};
Truth compute_truth(const Scenario& scenario, double rate_hz = 100.0);

struct WrittenScene {
  bool interrupted = false;  // `stop` was set: nothing was written
  std::filesystem::path site;
  std::filesystem::path truth;
  std::vector<std::filesystem::path> recordings;
  std::vector<std::filesystem::path> poses;  // one per moving array, site order
  std::filesystem::path reference;           // reference.jsonl (a reference_log); else empty
  double scale = 1.0;
};
// A moving array's pose file, beside its recording: "<id>.pose.jsonl".
std::string pose_file_name(const std::string& array_id);
// Its lines: t = k / pose_rate_hz from 0 to the first at or after `duration_s`.
std::vector<doa::PoseSample> pose_lines(const MovingArray& moving, double duration_s);
// As JSON lines: {"t", "position_m", "yaw_deg", "pitch_deg", "roll_deg"} (docs/scenarios.md).
std::string pose_lines_text(const std::vector<doa::PoseSample>& lines);

// A reference_log's lines (docs/calibration.md): {"t", "position_m", "position_std_m"} of its
// source every 1 / rate_hz s over the duration, each position with Gaussian noise of that std.
std::string reference_log_text(const Scenario& scenario);

// Creates `out_dir` and writes site.json (SPEC 3.1; recordings relative, the scenario's doa,
// fusion, zones, dds and http sections copied through), <array id>.wav (float32) per array and
// truth.json, and <id>.pose.jsonl per moving array, all of them or none (docs/contract.md). Throws
// std::runtime_error naming the file on I/O failure. A set `stop` (a signal) ends it between arrays
// with nothing written.
WrittenScene write_scene(const Scenario& scenario, const std::filesystem::path& out_dir,
                         const std::atomic<bool>* stop = nullptr);

// The site section of the scene as written to DIR/site.json.
nlohmann::json scene_site_json(const Scenario& scenario);

}  // namespace dronetrack::sim
