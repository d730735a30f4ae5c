#include "sim/render.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>

#include <sndfile.h>

#include "common/log.hpp"
#include "common/output_file.hpp"
#include "doa/array_geometry.hpp"
#include "sim/noise.hpp"
#include "sim/propagation.hpp"
#include "sim/random.hpp"
#include "sim/source_signal.hpp"

namespace dronetrack::sim {
namespace {

constexpr double kClipLimit = 1.0;
constexpr double kTargetPeak = 0.9;

std::size_t frames_of(const Scenario& scenario, std::size_t array_index) {
  double end_s = scenario.duration_s;
  if (array_index < scenario.recording_end_s.size() &&
      scenario.recording_end_s[array_index] > 0.0) {
    end_s = std::min(end_s, scenario.recording_end_s[array_index]);
  }
  return static_cast<std::size_t>(std::llround(end_s * scenario.sample_rate_hz));
}

std::size_t channel_count(const config::ArrayConfig& array) {
  int highest = -1;
  for (int channel : array.channel_map) highest = std::max(highest, channel);
  return std::max<std::size_t>(static_cast<std::size_t>(highest + 1), array.geometry.mic_count());
}

std::size_t channel_of(const config::ArrayConfig& array, std::size_t mic) {
  return mic < array.channel_map.size() ? static_cast<std::size_t>(array.channel_map[mic]) : mic;
}

const MovingArray* moving_array(const Scenario& scenario, std::size_t array_index) {
  if (array_index >= scenario.moving_arrays.size() || !scenario.moving_arrays[array_index])
    return nullptr;
  return &*scenario.moving_arrays[array_index];
}

// Where a mic is: fixed at its site position, or carried by its array's motion.
Receiver receiver_of(const Scenario& scenario, std::size_t array_index, std::size_t mic) {
  const auto& geometry = scenario.site.arrays[array_index].geometry;
  if (const MovingArray* moving = moving_array(scenario, array_index))
    return Receiver::carried(moving->motion, geometry.mics_m[mic]);
  return Receiver::fixed(geometry.mic_site_m(mic));
}

Eigen::Vector3d mic_centroid_array_m(const doa::ArrayGeometry& geometry) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& mic : geometry.mics_m) sum += mic;
  return geometry.mics_m.empty() ? sum
                                 : Eigen::Vector3d(sum / static_cast<double>(geometry.mic_count()));
}

// Renders scenes: synthesises each source once, over the emission times the chosen arrays need.
class Renderer {
 public:
  Renderer(const Scenario& scenario, const std::vector<std::size_t>& arrays)
      : scenario_(scenario), sources_(scenario.sources.size()) {
    const double c = scenario.site.speed_of_sound_mps;
    for (std::size_t s = 0; s < scenario.sources.size(); ++s) {
      // t_e(t) increases with t, so the earliest emission any mic needs is at t = 0.
      double earliest = 0.0;
      for (std::size_t a : arrays) {
        const auto& geometry = scenario.site.arrays[a].geometry;
        for (std::size_t mic = 0; mic < geometry.mic_count(); ++mic) {
          for (bool image : paths()) {
            earliest = std::min(
                earliest, solve_emission_time(scenario.sources[s].trajectory,
                                              receiver_of(scenario, a, mic).at(0.0), 0.0, c, image)
                              .emission_time_s);
          }
        }
      }
      double latest_recording_s = 0.0;  // a late clock or channel needs earlier emissions
      for (std::size_t a : arrays) {
        for (std::size_t mic = 0;
             a < scenario.array_errors.size() && mic < scenario.site.arrays[a].geometry.mic_count();
             ++mic)
          latest_recording_s =
              std::max(latest_recording_s, scenario.array_errors[a].recording_delay_s(mic));
      }
      sources_[s] = synthesise_source(scenario, s, earliest - 0.01 - latest_recording_s,
                                      scenario.duration_s + 2.0 * EmissionGrid::kDefaultStep_s);
    }
  }

  std::vector<bool> paths() const {
    if (scenario_.ground_reflection > 0.0) return {false, true};
    return {false};
  }

  // Adds the sound of the drones (drones = true) or of the interferers to `out`.
  void add_sources(std::size_t array_index, bool drones, RenderedArray& out) const {
    const auto& array = scenario_.site.arrays[array_index];
    const double c = scenario_.site.speed_of_sound_mps;
    const std::size_t frames = out.frames();
    const double end_s = static_cast<double>(frames) / scenario_.sample_rate_hz;
    struct Path {
      EmissionGrid grid;
      std::size_t source, channel;
      double gain;
    };
    std::vector<Path> paths_to_render;
    for (std::size_t s = 0; s < scenario_.sources.size(); ++s) {
      if ((scenario_.sources[s].kind == SourceKind::drone) != drones) continue;
      for (std::size_t mic = 0; mic < array.geometry.mic_count(); ++mic) {
        for (bool image : paths()) {
          const double recording_delay_s =
              array_index < scenario_.array_errors.size()
                  ? scenario_.array_errors[array_index].recording_delay_s(mic)
                  : 0.0;
          paths_to_render.push_back({EmissionGrid(scenario_.sources[s].trajectory,
                                                  receiver_of(scenario_, array_index, mic), image,
                                                  c, 0.0, end_s + EmissionGrid::kDefaultStep_s,
                                                  EmissionGrid::kDefaultStep_s, recording_delay_s),
                                     s, channel_of(array, mic),
                                     image ? scenario_.ground_reflection : 1.0});
        }
      }
    }
    // In chunks, all paths per chunk: the chunk of output stays in cache instead of the whole
    // recording streaming through memory once per path.
    constexpr std::size_t kChunk = 4096;
    for (std::size_t begin = 0; begin < frames; begin += kChunk) {
      const std::size_t end = std::min(frames, begin + kChunk);
      for (const Path& path : paths_to_render) {
        path.grid.accumulate(sources_[path.source], path.gain, scenario_.sample_rate_hz, begin, end,
                             out.samples.data() + path.channel, out.channels);
      }
    }
  }

  RenderedArray blank(std::size_t array_index) const {
    RenderedArray out;
    const auto& array = scenario_.site.arrays[array_index];
    out.id = array.geometry.id;
    out.sample_rate_hz = scenario_.sample_rate_hz;
    out.channels = channel_count(array);
    out.samples.assign(frames_of(scenario_, array_index) * out.channels, 0.0f);
    return out;
  }

  double drone_inband_power(const RenderedArray& drones) const {
    return measure_inband_power(drones.samples.data(), drones.channels, drones.frames(),
                                scenario_.sample_rate_hz, scenario_.site.doa.bands_hz);
  }

  RenderedArray render(std::size_t array_index) const {
    RenderedArray out = blank(array_index);
    add_sources(array_index, true, out);
    const NoiseSpec& noise = scenario_.noise;
    const bool needs_snr =
        noise.sensor.snr_db || noise.wind.snr_db || noise.ambient.snr_db || noise.impulsive.snr_db;
    double signal_power = 0.0;
    if (needs_snr) {
      std::size_t reference = array_index;
      if (!noise.snr_reference_array.empty()) {
        reference = static_cast<std::size_t>(scenario_.site.array_index(noise.snr_reference_array));
      }
      if (reference == array_index) {
        signal_power = drone_inband_power(out);
      } else {
        RenderedArray reference_drones = blank(reference);
        add_sources(reference, true, reference_drones);
        signal_power = drone_inband_power(reference_drones);
      }
    }
    add_sources(array_index, false, out);
    const auto& geometry = scenario_.site.arrays[array_index].geometry;
    double largest_spacing_m = 0.0;
    for (std::size_t i = 0; i < geometry.mic_count(); ++i) {
      for (std::size_t j = i + 1; j < geometry.mic_count(); ++j) {
        largest_spacing_m =
            std::max(largest_spacing_m, (geometry.mics_m[i] - geometry.mics_m[j]).norm());
      }
    }
    auto add = [&](const NoiseLevel& level, NoiseKind kind) {
      if (!level.enabled) return;
      NoiseShape shape;
      shape.kind = kind;
      shape.sample_rate_hz = scenario_.sample_rate_hz;
      shape.wind_corner_hz = noise.wind_corner_hz;
      shape.wind_gust_depth = noise.wind_gust_depth;
      shape.ambient_coherent_below_hz =
          noise.ambient_coherent_below_hz > 0.0
              ? noise.ambient_coherent_below_hz
              : scenario_.site.speed_of_sound_mps / (2.0 * std::max(largest_spacing_m, 0.01));
      double rms = 0.0;
      if (level.level_db_spl) {
        rms = full_scale_rms(*level.level_db_spl, scenario_.full_scale_db_spl);
      } else {
        const double inband_noise = signal_power / std::pow(10.0, *level.snr_db / 10.0);
        rms = std::sqrt(inband_noise / shape.inband_fraction(scenario_.site.doa.bands_hz));
      }
      add_noise(shape, rms, scenario_.seed, array_index, out.channels, out.frames(),
                out.samples.data());
    };
    // A dead mic hears nothing: its channel records its own sensor noise alone.
    const ArrayErrors* errors = array_index < scenario_.array_errors.size()
                                    ? &scenario_.array_errors[array_index]
                                    : nullptr;
    const auto& array = scenario_.site.arrays[array_index];
    std::vector<std::size_t> dead_channels;
    if (errors != nullptr)
      for (std::size_t mic = 0; mic < array.geometry.mic_count(); ++mic)
        if (errors->dead(mic)) dead_channels.push_back(channel_of(array, mic));
    for (const std::size_t channel : dead_channels)
      for (std::size_t n = 0; n < out.frames(); ++n) out.samples[n * out.channels + channel] = 0.0F;
    add(noise.sensor, NoiseKind::sensor);
    std::vector<float> dead_samples;
    for (const std::size_t channel : dead_channels)
      for (std::size_t n = 0; n < out.frames(); ++n)
        dead_samples.push_back(out.samples[n * out.channels + channel]);
    add(noise.wind, NoiseKind::wind);
    add(noise.ambient, NoiseKind::ambient);
    for (std::size_t d = 0; d < dead_channels.size(); ++d)
      for (std::size_t n = 0; n < out.frames(); ++n)
        out.samples[n * out.channels + dead_channels[d]] = dead_samples[d * out.frames() + n];
    if (noise.impulsive.enabled) {
      // Scaled like white sensor noise: the RMS a Gaussian burst of the same c would have.
      double rms = 0.0;
      if (noise.impulsive.level_db_spl) {
        rms = full_scale_rms(*noise.impulsive.level_db_spl, scenario_.full_scale_db_spl);
      } else {
        NoiseShape white;
        white.sample_rate_hz = scenario_.sample_rate_hz;
        const double inband_noise = signal_power / std::pow(10.0, *noise.impulsive.snr_db / 10.0);
        rms = std::sqrt(inband_noise / white.inband_fraction(scenario_.site.doa.bands_hz));
      }
      add_impulsive_noise(noise.impulsive, rms, scenario_.sample_rate_hz, scenario_.seed,
                          array_index, out.channels, out.frames(), out.samples.data());
    }
    // A channel's gain scales all it records: the mic's sensitivity and its preamplifier; a
    // flipped mic (or swapped wires) records it all inverted.
    if (errors != nullptr) {
      for (std::size_t mic = 0; mic < array.geometry.mic_count(); ++mic) {
        const auto gain =
            static_cast<float>(errors->gain(mic) * (errors->flipped(mic) ? -1.0 : 1.0));
        if (gain == 1.0F) continue;
        const std::size_t channel = channel_of(array, mic);
        for (std::size_t n = 0; n < out.frames(); ++n)
          out.samples[n * out.channels + channel] *= gain;
      }
      // Two mics wired to each other's inputs: each channel records what the other mic hears.
      for (const auto& [a, b] : errors->swapped_channels) {
        const std::size_t first = channel_of(array, static_cast<std::size_t>(a));
        const std::size_t second = channel_of(array, static_cast<std::size_t>(b));
        for (std::size_t n = 0; n < out.frames(); ++n)
          std::swap(out.samples[n * out.channels + first], out.samples[n * out.channels + second]);
      }
    }
    return out;
  }

 private:
  const Scenario& scenario_;
  std::vector<SourceBuffer> sources_;
};

nlohmann::json vector_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// Into `out`'s temporary, by descriptor: libsndfile seeks back to finish the header.
void write_wav(OutputFile& out, const RenderedArray& array) {
  SF_INFO info{};
  info.samplerate = static_cast<int>(std::lround(array.sample_rate_hz));
  info.channels = static_cast<int>(array.channels);
  info.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
  SNDFILE* file = sf_open_fd(out.descriptor(), SFM_WRITE, &info, SF_FALSE);
  if (!file) throw OutputError(out.name() + ": cannot write (" + sf_strerror(nullptr) + ")");
  const auto frames = static_cast<sf_count_t>(array.frames());
  const sf_count_t written = sf_writef_float(file, array.samples.data(), frames);
  const std::string error = sf_strerror(file);
  const int closed = sf_close(file);
  if (written != frames || closed != 0)
    throw OutputError(out.name() + ": write failed (" + error + ")");
}

void write_json(OutputFile& out, const nlohmann::json& document, int indent) {
  out.write(document.dump(indent) + "\n");
}

}  // namespace

RenderedArray render_array(const Scenario& scenario, std::size_t array_index) {
  if (array_index >= scenario.site.arrays.size()) {
    throw std::out_of_range("render_array: no array " + std::to_string(array_index));
  }
  return Renderer(scenario, {array_index}).render(array_index);
}

RenderedScene render_scene(const Scenario& scenario, const std::atomic<bool>* stop) {
  std::vector<std::size_t> all(scenario.site.arrays.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  const Renderer renderer(scenario, all);
  RenderedScene scene;
  for (std::size_t i : all) {
    if (stop && stop->load()) {
      scene.interrupted = true;
      return scene;
    }
    scene.arrays.push_back(renderer.render(i));
    for (float value : scene.arrays.back().samples) {
      scene.peak_before_scaling =
          std::max(scene.peak_before_scaling, static_cast<double>(std::abs(value)));
    }
  }
  if (scene.peak_before_scaling >= kClipLimit) {
    scene.scale = kTargetPeak / scene.peak_before_scaling;
    log::warn("sim: the scene would clip (peak ", scene.peak_before_scaling,
              " of full scale); all arrays scaled by ", scene.scale, " (",
              20.0 * std::log10(scene.scale), " dB) to a peak of ", kTargetPeak);
    const auto factor = static_cast<float>(scene.scale);
    for (auto& array : scene.arrays) {
      for (float& value : array.samples) value *= factor;
    }
  }
  return scene;
}

Truth compute_truth(const Scenario& scenario, double rate_hz) {
  Truth truth;
  truth.rate_hz = rate_hz;
  for (const auto& array : scenario.site.arrays) truth.array_ids.push_back(array.geometry.id);
  const auto count = static_cast<std::size_t>(std::floor(scenario.duration_s * rate_hz + 1e-9)) + 1;
  const double c = scenario.site.speed_of_sound_mps;
  for (const auto& source : scenario.sources) {
    SourceTruth out;
    out.id = source.id;
    out.is_drone = source.kind == SourceKind::drone;
    out.source_class = source.source_class;
    out.direction.resize(scenario.site.arrays.size());
    for (std::size_t i = 0; i < count; ++i) {
      const double t_s = static_cast<double>(i) / rate_hz;
      const TrajectoryState state = source.trajectory.at(t_s);
      out.t_s.push_back(t_s);
      out.position_m.push_back(state.position_m);
      out.velocity_mps.push_back(state.velocity_mps);
      for (std::size_t a = 0; a < scenario.site.arrays.size(); ++a) {
        const auto& geometry = scenario.site.arrays[a].geometry;
        const MovingArray* moving = moving_array(scenario, a);
        // A moving array's centre where it is when the sound arrives.
        const Eigen::Vector3d centre =
            moving ? moving->motion.point_state(mic_centroid_array_m(geometry), t_s).position_m
                   : geometry.centre_site_m();
        const EmissionSolution emission = solve_emission_time(source.trajectory, centre, t_s, c);
        out.direction[a].push_back(
            (source.trajectory.position(emission.emission_time_s) - centre).normalized());
      }
    }
    truth.sources.push_back(std::move(out));
  }
  return truth;
}

nlohmann::json Truth::to_json(const Scenario& scenario) const {
  nlohmann::json document;
  document["sources"] = nlohmann::json::array();
  document["interferers"] = nlohmann::json::array();
  for (const auto& source : sources) {
    nlohmann::json entry;
    entry["id"] = source.id;
    entry["kind"] = source.is_drone ? "drone" : "interferer";
    entry["class"] = source.source_class;
    entry["t"] = source.t_s;
    auto& positions = entry["position_m"] = nlohmann::json::array();
    auto& velocities = entry["velocity_mps"] = nlohmann::json::array();
    for (std::size_t i = 0; i < source.t_s.size(); ++i) {
      positions.push_back(vector_json(source.position_m[i]));
      velocities.push_back(vector_json(source.velocity_mps[i]));
    }
    auto& doa = entry["doa"] = nlohmann::json::object();
    for (std::size_t a = 0; a < array_ids.size(); ++a) {
      auto& directions = doa[array_ids[a]]["direction"] = nlohmann::json::array();
      for (const auto& direction : source.direction[a])
        directions.push_back(vector_json(direction));
    }
    document[source.is_drone ? "sources" : "interferers"].push_back(std::move(entry));
  }
  document["rate_hz"] = rate_hz;
  document["duration_s"] = scenario.duration_s;
  document["speed_of_sound_mps"] = scenario.site.speed_of_sound_mps;
  auto& arrays = document["arrays"] = nlohmann::json::object();
  for (std::size_t a = 0; a < scenario.site.arrays.size(); ++a) {
    const auto& geometry = scenario.site.arrays[a].geometry;
    arrays[geometry.id]["centre_m"] = vector_json(geometry.centre_site_m());
    const double end_s = a < scenario.recording_end_s.size() && scenario.recording_end_s[a] > 0.0
                             ? scenario.recording_end_s[a]
                             : scenario.duration_s;
    arrays[geometry.id]["recording_end_s"] = end_s;
    if (moving_array(scenario, a)) arrays[geometry.id]["pose_file"] = pose_file_name(geometry.id);
    if (scenario.array_error_spec.enabled && a < scenario.array_errors.size())
      arrays[geometry.id]["errors"] = scenario.array_errors[a].to_json();
  }
  return document;
}

std::string reference_log_text(const Scenario& scenario) {
  const ReferenceLogSpec& spec = scenario.reference_log;
  std::string text;
  const SourceSpec* source = nullptr;
  for (const auto& candidate : scenario.sources)
    if (candidate.id == spec.source) source = &candidate;
  if (!spec.enabled || source == nullptr) return text;
  Random random(scenario.seed, stream_id(0xCA1C));
  const auto last = static_cast<std::size_t>(std::floor(scenario.duration_s * spec.rate_hz + 1e-9));
  for (std::size_t k = 0; k <= last; ++k) {
    const double t_s = static_cast<double>(k) / spec.rate_hz;
    const double x = random.normal(), y = random.normal(), z = random.normal();
    const Eigen::Vector3d fix =
        source->trajectory.position(t_s) + spec.position_std_m * Eigen::Vector3d(x, y, z);
    const nlohmann::json line = {
        {"t", t_s}, {"position_m", vector_json(fix)}, {"position_std_m", spec.position_std_m}};
    text += line.dump() + "\n";
  }
  return text;
}

std::string pose_file_name(const std::string& array_id) { return array_id + ".pose.jsonl"; }

std::vector<doa::PoseSample> pose_lines(const MovingArray& moving, double duration_s) {
  // From t = 0 to the first line at or after the end, so the pose covers the whole recording.
  const auto last = static_cast<std::size_t>(std::ceil(duration_s * moving.pose_rate_hz - 1e-9));
  std::vector<doa::PoseSample> lines;
  lines.reserve(last + 1);
  for (std::size_t k = 0; k <= last; ++k)
    lines.push_back(moving.motion.pose(static_cast<double>(k) / moving.pose_rate_hz));
  return lines;
}

std::string pose_lines_text(const std::vector<doa::PoseSample>& lines) {
  std::string text;
  for (const auto& line : lines) {
    const nlohmann::json document = {{"t", line.time_s},
                                     {"position_m", vector_json(line.position_m)},
                                     {"yaw_deg", line.yaw_deg},
                                     {"pitch_deg", line.pitch_deg},
                                     {"roll_deg", line.roll_deg}};
    text += document.dump() + "\n";
  }
  return text;
}

nlohmann::json scene_site_json(const Scenario& scenario) {
  nlohmann::json site = scenario.site_json;
  if (!site.contains("description") && !scenario.description.empty()) {
    site["description"] = "Simulated: " + scenario.description;
  }
  for (std::size_t a = 0; a < scenario.site.arrays.size(); ++a) {
    const std::string& id = scenario.site.arrays[a].geometry.id;
    site["arrays"][a]["recording"] = id + ".wav";
    if (const MovingArray* moving = moving_array(scenario, a)) {
      // Where it starts, for readers that only look at the fixed keys; the pose file rules.
      const doa::PoseSample start = moving->motion.pose(0.0);
      site["arrays"][a]["position_m"] = vector_json(start.position_m);
      site["arrays"][a]["yaw_deg"] = start.yaw_deg;
      site["arrays"][a]["pose_file"] = pose_file_name(id);
    }
  }
  return site;
}

WrittenScene write_scene(const Scenario& scenario, const std::filesystem::path& out_dir,
                         const std::atomic<bool>* stop) {
  std::error_code error;
  std::filesystem::create_directories(out_dir, error);
  if (error)
    throw std::runtime_error(out_dir.string() + ": cannot create (" + error.message() + ")");
  WrittenScene written;
  written.site = out_dir / "site.json";
  written.truth = out_dir / "truth.json";
  std::vector<NamedPath> outputs{{"the scene's site", written.site},
                                 {"the scene's truth", written.truth}};
  for (std::size_t a = 0; a < scenario.site.arrays.size(); ++a) {
    const std::string& id = scenario.site.arrays[a].geometry.id;
    written.recordings.push_back(out_dir / (id + ".wav"));
    outputs.push_back({"array " + id + "'s recording", written.recordings.back()});
    if (moving_array(scenario, a)) {
      written.poses.push_back(out_dir / pose_file_name(id));
      outputs.push_back({"array " + id + "'s pose file", written.poses.back()});
    }
  }
  if (scenario.reference_log.enabled) {
    written.reference = out_dir / "reference.jsonl";
    outputs.push_back({"the scene's reference log", written.reference});
  }
  check_output_paths({{"the scenario", scenario.file}}, outputs);
  // The pose lines before the long render: the scenario checked its turns over its own
  // duration, a longer --duration-s may reach turns it did not.
  std::vector<std::string> pose_texts;
  for (std::size_t a = 0; a < scenario.site.arrays.size(); ++a) {
    const MovingArray* moving = moving_array(scenario, a);
    if (!moving) continue;
    const std::vector<doa::PoseSample> lines = pose_lines(*moving, scenario.duration_s);
    for (std::size_t k = 1; k < lines.size(); ++k) {
      const double turn_deg = std::abs(doa::wrap_deg_180(lines[k].yaw_deg - lines[k - 1].yaw_deg));
      if (turn_deg > kMaxPoseYawStep_deg)
        throw std::runtime_error("array " + scenario.site.arrays[a].geometry.id + " turns " +
                                 std::to_string(turn_deg) + " deg between pose lines at t = " +
                                 std::to_string(lines[k].time_s) + " s; raise its pose_rate_hz");
    }
    pose_texts.push_back(pose_lines_text(lines));
  }

  const RenderedScene scene = render_scene(scenario, stop);
  written.scale = scene.scale;
  written.interrupted = scene.interrupted;
  if (written.interrupted) return written;
  // All files of the scene or none: each goes to a temporary, and they are renamed into place
  // only once every one is written (a scene with a new site.json and old recordings is worse
  // than the old scene).
  std::vector<std::unique_ptr<OutputFile>> files;
  for (std::size_t i = 0; i < scene.arrays.size(); ++i) {
    files.push_back(std::make_unique<OutputFile>(written.recordings.at(i)));
    write_wav(*files.back(), scene.arrays[i]);
  }
  for (std::size_t pose = 0; pose < written.poses.size(); ++pose) {
    files.push_back(std::make_unique<OutputFile>(written.poses[pose]));
    files.back()->write(pose_texts.at(pose));
  }
  if (!written.reference.empty()) {
    files.push_back(std::make_unique<OutputFile>(written.reference));
    files.back()->write(reference_log_text(scenario));
  }
  files.push_back(std::make_unique<OutputFile>(written.site));
  write_json(*files.back(), scene_site_json(scenario), 2);
  files.push_back(std::make_unique<OutputFile>(written.truth));
  write_json(*files.back(), compute_truth(scenario).to_json(scenario), -1);
  if (stop && stop->load()) {  // the files are discarded with their temporaries
    written.interrupted = true;
    return written;
  }
  for (auto& file : files) file->commit();
  return written;
}

}  // namespace dronetrack::sim
