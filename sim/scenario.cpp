#include "sim/scenario.hpp"

#include <cmath>
#include <fstream>
#include <numbers>
#include <set>
#include <sstream>

#include <sndfile.h>

#include "common/input_file.hpp"
#include "config/config_reader.hpp"
#include "doa/array_geometry.hpp"

namespace dronetrack::sim {
namespace {

using config::Diagnostics;
using config::ObjectReader;
using nlohmann::json;

constexpr double kMaxSpeed_mps = 200.0;

std::optional<std::vector<Eigen::Vector3d>> read_points(ObjectReader& reader,
                                                        const std::string& key,
                                                        std::size_t min_count) {
  std::vector<Eigen::Vector3d> points;
  bool all_good = true;
  const bool listed =
      reader.for_each(key, true, [&](const json& node, const std::string& element_path) {
        auto point = config::read_vector3(node, element_path, reader.diagnostics());
        if (point) {
          points.push_back(*point);
        } else {
          all_good = false;
        }
      });
  if (!listed || !all_good) return std::nullopt;
  if (points.size() < min_count) {
    reader.diagnostics().error(reader.path_of(key), "needs at least " + std::to_string(min_count) +
                                                        " points, got " +
                                                        std::to_string(points.size()));
    return std::nullopt;
  }
  return points;
}

// Checks the legs of a polyline: no zero-length leg, no reversal (a turn of ~180 degrees cannot
// be rounded). Returns false after reporting.
bool check_legs(const std::vector<Eigen::Vector3d>& points, bool closed, const std::string& path,
                Diagnostics& diagnostics) {
  const std::size_t count = points.size();
  const std::size_t legs = closed ? count : count - 1;
  bool good = true;
  for (std::size_t leg = 0; leg < legs; ++leg) {
    if ((points[(leg + 1) % count] - points[leg]).norm() < 1e-3) {
      diagnostics.error(path + "[" + std::to_string((leg + 1) % count) + "]",
                        "repeats the previous point (legs must be longer than 1 mm)");
      good = false;
    }
  }
  if (!good) return false;
  for (std::size_t i = 0; i < count; ++i) {
    if (!closed && (i == 0 || i == count - 1)) continue;
    const Eigen::Vector3d before = (points[i] - points[(i + count - 1) % count]).normalized();
    const Eigen::Vector3d after = (points[(i + 1) % count] - points[i]).normalized();
    if (before.dot(after) < -0.9998) {
      diagnostics.error(path + "[" + std::to_string(i) + "]",
                        "the path reverses here; add a point to turn around");
      good = false;
    }
  }
  return good;
}

std::optional<Trajectory> parse_trajectory(ObjectReader& reader) {
  Diagnostics& diagnostics = reader.diagnostics();
  const std::string type = reader.choice(
      "type", "hover", {"hover", "static", "straight", "circle", "rectangle", "waypoints"});
  const std::size_t errors_before = diagnostics.errors.size();
  auto ok = [&] { return diagnostics.errors.size() == errors_before; };
  if (type == "hover" || type == "static") {
    auto position = reader.vector3("position_m", true);
    if (!position || !ok()) return std::nullopt;
    return Trajectory::fixed(*position);
  }
  if (type == "straight") {
    auto start = reader.vector3("start_m", true);
    const bool has_velocity = reader.has("velocity_mps");
    const bool has_end = reader.has("end_m");
    if (has_velocity == has_end) {
      diagnostics.error(reader.path(),
                        "a straight pass needs either velocity_mps or end_m with speed_mps");
      return std::nullopt;
    }
    Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
    if (has_velocity) {
      if (auto given = reader.vector3("velocity_mps", true)) velocity = *given;
      if (velocity.norm() > kMaxSpeed_mps) {
        diagnostics.error(reader.path_of("velocity_mps"), "faster than 200 m/s");
      }
    } else {
      auto end = reader.vector3("end_m", true);
      auto speed = reader.required_number("speed_mps", 0.0, kMaxSpeed_mps);
      if (end && start && speed) {
        if ((*end - *start).norm() < 1e-3) {
          diagnostics.error(reader.path_of("end_m"), "equals start_m");
        } else {
          velocity = (*end - *start).normalized() * *speed;
        }
      }
    }
    if (!start || !ok()) return std::nullopt;
    return Trajectory::straight(*start, velocity);
  }
  if (type == "circle") {
    auto centre = reader.vector3("centre_m", true);
    auto radius = reader.required_number("radius_m", 0.1, 1e5);
    auto speed = reader.required_number("speed_mps", 0.01, kMaxSpeed_mps);
    const double start_angle = reader.number("start_angle_deg", 0.0, -360.0, 360.0);
    const bool clockwise = reader.boolean("clockwise", false);
    if (!centre || !radius || !speed || !ok()) return std::nullopt;
    return Trajectory::circle(*centre, *radius, *speed, start_angle, clockwise);
  }
  if (type == "rectangle") {
    auto centre = reader.vector3("centre_m", true);
    auto size = reader.numbers("size_m", 2, true);
    auto speed = reader.required_number("speed_mps", 0.01, kMaxSpeed_mps);
    const double corner_radius = reader.number("corner_radius_m", 5.0, 0.0, 1e4);
    const double yaw = reader.number("yaw_deg", 0.0, -360.0, 360.0) * std::numbers::pi / 180.0;
    const bool clockwise = reader.boolean("clockwise", false);
    if (size && ((*size)[0] < 0.1 || (*size)[1] < 0.1)) {
      diagnostics.error(reader.path_of("size_m"), "both sides must be at least 0.1 m");
    }
    if (!centre || !size || !speed || !ok()) return std::nullopt;
    const double half_x = (*size)[0] / 2.0;
    const double half_y = (*size)[1] / 2.0;
    std::vector<Eigen::Vector2d> local{
        {-half_x, -half_y}, {half_x, -half_y}, {half_x, half_y}, {-half_x, half_y}};
    if (clockwise) std::swap(local[1], local[3]);
    std::vector<Eigen::Vector3d> corners;
    for (const auto& corner : local) {
      corners.emplace_back((*centre)[0] + std::cos(yaw) * corner[0] - std::sin(yaw) * corner[1],
                           (*centre)[1] + std::sin(yaw) * corner[0] + std::cos(yaw) * corner[1],
                           (*centre)[2]);
    }
    return Trajectory::through_points(corners, *speed, corner_radius, true);
  }
  // waypoints
  auto points = read_points(reader, "points_m", 2);
  auto speed = reader.required_number("speed_mps", 0.01, kMaxSpeed_mps);
  const double turn_radius = reader.number("turn_radius_m", 5.0, 0.0, 1e4);
  const bool loop = reader.boolean("loop", false);
  if (!points || !speed || !ok()) return std::nullopt;
  if (loop && points->size() < 3) {
    diagnostics.error(reader.path_of("points_m"), "a loop needs at least 3 points");
    return std::nullopt;
  }
  if (!check_legs(*points, loop, reader.path_of("points_m"), diagnostics)) return std::nullopt;
  return Trajectory::through_points(*points, *speed, turn_radius, loop);
}

void parse_signal(ObjectReader& reader, SourceSpec& source, double sample_rate_hz,
                  const std::filesystem::path& base_dir) {
  Diagnostics& diagnostics = reader.diagnostics();
  const double max_hz = 0.4 * sample_rate_hz;
  const std::string fallback = source.kind == SourceKind::drone ? "rotor" : "noise";
  const std::string type = reader.choice(
      "type", fallback,
      {"rotor", "recording", "noise", "tones", "engine", "generator", "propeller", "chirps"});
  if (type == "rotor" || type == "engine" || type == "generator" || type == "propeller") {
    source.signal_type = SignalType::rotor;
    RotorSignal& rotor = source.rotor;
    // The non-drone harmonic sources are rotors with other defaults (docs/scenarios.md).
    if (type == "engine") {  // a four-cylinder at 1800 rpm under tyre and road noise
      rotor = {60.0, 0.05, 8.0, 60, -3.0, 6.0, 500.0, -18.0, 300.0, 4000.0};
    } else if (type == "generator") {  // locked to 50 Hz mains, exhaust broadband
      rotor = {50.0, 0.0005, 20.0, 80, -6.0, -6.0, 0.0, 0.0, 50.0, 5000.0};
      rotor.blade_pass_hz = reader.number("mains_hz", rotor.blade_pass_hz, 10.0, 1000.0);
    } else if (type == "propeller") {  // a two-blade prop at 2550 rpm
      rotor = {85.0, 0.01, 10.0, 60, -4.0, -6.0, 0.0, 0.0, 20.0, 0.0};
    }
    rotor.blade_pass_hz = reader.number("blade_pass_hz", rotor.blade_pass_hz, 20.0, 1000.0);
    rotor.rpm_wander = reader.number("rpm_wander", rotor.rpm_wander, 0.0, 0.3);
    rotor.wander_period_s = reader.number("wander_period_s", rotor.wander_period_s, 0.5, 600.0);
    rotor.harmonics = reader.integer("harmonics", rotor.harmonics, 1, 200);
    rotor.slope_db_per_octave =
        reader.number("slope_db_per_octave", rotor.slope_db_per_octave, -24.0, 6.0);
    rotor.broadband_db = reader.number("broadband_db", rotor.broadband_db, -80.0, 20.0);
    rotor.rolloff_corner_hz =
        reader.number("rolloff_corner_hz", rotor.rolloff_corner_hz, 0.0, max_hz);
    rotor.rolloff_db_per_octave =
        reader.number("rolloff_db_per_octave", rotor.rolloff_db_per_octave, -60.0, 0.0);
    rotor.broadband_low_hz = reader.number("broadband_low_hz", rotor.broadband_low_hz, 0.0, max_hz);
    rotor.broadband_high_hz =
        reader.number("broadband_high_hz", rotor.broadband_high_hz, 0.0, max_hz);
    if (rotor.broadband_high_hz > 0.0 && rotor.broadband_high_hz <= rotor.broadband_low_hz + 10.0)
      diagnostics.error(reader.path_of("broadband_high_hz"),
                        "must be more than 10 Hz above broadband_low_hz");
  } else if (type == "chirps") {
    source.signal_type = SignalType::chirps;
    ChirpsSignal& chirps = source.chirps;
    chirps.low_hz = reader.number("low_hz", chirps.low_hz, 100.0, max_hz);
    chirps.high_hz = reader.number("high_hz", std::min(chirps.high_hz, max_hz), 100.0, max_hz);
    if (chirps.high_hz <= chirps.low_hz)
      diagnostics.error(reader.path_of("high_hz"), "must be above low_hz");
    chirps.min_duration_s = reader.number("min_duration_s", chirps.min_duration_s, 0.01, 5.0);
    chirps.max_duration_s = reader.number("max_duration_s", chirps.max_duration_s, 0.01, 5.0);
    if (chirps.max_duration_s < chirps.min_duration_s)
      diagnostics.error(reader.path_of("max_duration_s"), "must not be below min_duration_s");
    chirps.mean_interval_s = reader.number("mean_interval_s", chirps.mean_interval_s, 0.05, 600.0);
  } else if (type == "recording") {
    source.signal_type = SignalType::recording;
    RecordingSignal& recording = source.recording;
    const auto file = reader.required_string("file");
    recording.start_s = reader.number("start_s", 0.0, 0.0, 1e6);
    if (reader.has("end_s")) recording.end_s = reader.required_number("end_s", 0.0, 1e6);
    if (!file) return;
    const std::filesystem::path path(*file);
    recording.file = path.is_absolute() ? path : base_dir / path;
    SF_INFO info{};
    SNDFILE* handle = sf_open(recording.file.string().c_str(), SFM_READ, &info);
    if (!handle) {
      diagnostics.error(reader.path_of("file"),
                        recording.file.string() + ": cannot read (" + sf_strerror(nullptr) + ")");
      return;
    }
    sf_close(handle);
    const double length_s = static_cast<double>(info.frames) / info.samplerate;
    const double end_s = recording.end_s.value_or(length_s);
    if (end_s > length_s + 1e-9) {
      diagnostics.error(reader.path_of("end_s"), "beyond the end of " + recording.file.string() +
                                                     " (" + std::to_string(length_s) + " s)");
    } else if (end_s - recording.start_s < 0.5) {
      diagnostics.error(reader.path(), "the looped part [start_s, end_s) must be at least 0.5 s");
    }
  } else if (type == "noise") {
    source.signal_type = SignalType::noise;
    source.noise.low_hz = reader.number("low_hz", source.noise.low_hz, 0.0, max_hz);
    source.noise.high_hz =
        reader.number("high_hz", std::min(source.noise.high_hz, max_hz), 1.0, max_hz);
    if (source.noise.low_hz >= source.noise.high_hz) {
      diagnostics.error(reader.path_of("high_hz"), "must be above low_hz");
    }
  } else {
    source.signal_type = SignalType::tones;
    if (auto frequencies = reader.numbers("frequencies_hz", 0, true)) {
      for (std::size_t i = 0; i < frequencies->size(); ++i) {
        const double frequency = (*frequencies)[i];
        if (frequency <= 0.0 || frequency > max_hz) {
          std::ostringstream what;
          what << "must be in (0, " << max_hz << "] (0.4 x sample rate), got " << frequency;
          diagnostics.error(reader.path_of("frequencies_hz") + "[" + std::to_string(i) + "]",
                            what.str());
        }
      }
      source.tones.frequencies_hz = *frequencies;
    }
    if (auto levels = reader.numbers("relative_db", 0, false)) {
      if (levels->size() != source.tones.frequencies_hz.size()) {
        diagnostics.error(reader.path_of("relative_db"), "needs one level per frequency");
      }
      source.tones.relative_db = *levels;
    }
    source.tones.relative_db.resize(source.tones.frequencies_hz.size(), 0.0);
  }
}

void parse_noise_level(ObjectReader& parent, const std::string& key, NoiseLevel& level) {
  if (!parent.has(key)) {
    parent.accept(key);
    return;
  }
  ObjectReader reader = parent.object(key);
  const bool has_snr = reader.has("snr_db");
  const bool has_level = reader.has("level_db");
  if (has_snr == has_level) {
    reader.diagnostics().error(reader.path(), "give exactly one of snr_db or level_db");
  }
  if (has_snr) level.snr_db = reader.required_number("snr_db", -60.0, 100.0);
  if (has_level) level.level_db_spl = reader.required_number("level_db", -20.0, 160.0);
  level.enabled = level.snr_db.has_value() || level.level_db_spl.has_value();
}

// A list of {"array": id, "mic": index} (or, for pairs, {"array": id, "mics": [a, b]}, two
// different mics): the array must be the site's, the mics its mics.
// What a list of array_errors names: one mic ({"array", "mic"}), two ({"array", "mics": [a,
// b]}) or one channel and its delay ({"array", "channel", "delay_s"}).
enum class MicRefKind { mic, pair, channel_delay };

void parse_mic_refs(ObjectReader& parent, const std::string& key, const config::SiteConfig& site,
                    std::vector<MicRef>& out, MicRefKind kind = MicRefKind::mic) {
  const bool pairs = kind == MicRefKind::pair;
  const std::string mic_key = pairs                               ? "mics"
                              : kind == MicRefKind::channel_delay ? "channel"
                                                                  : "mic";
  parent.for_each(key, false, [&](const nlohmann::json& element, const std::string& path) {
    ObjectReader reader(element, path, parent.diagnostics());
    const std::string id = reader.required_string("array").value_or("");
    const int array = id.empty() ? -1 : site.array_index(id);
    if (!id.empty() && array < 0) {
      reader.diagnostics().error(reader.path_of("array"), "no array '" + id + "' in the site");
      reader.accept(mic_key);
      if (kind == MicRefKind::channel_delay) reader.accept("delay_s");
      return;
    }
    const int mics =
        array < 0
            ? 8
            : static_cast<int>(site.arrays[static_cast<std::size_t>(array)].geometry.mic_count());
    if (!reader.has(mic_key)) {
      reader.diagnostics().error(reader.path_of(mic_key), "required " + mic_key + " is missing");
      if (kind == MicRefKind::channel_delay) reader.accept("delay_s");
      return;
    }
    MicRef ref{id, 0, -1, 0.0};
    if (pairs) {
      const std::optional<std::vector<double>> both = reader.numbers(mic_key, 2, true);
      if (!both) return;
      const double a = (*both)[0], b = (*both)[1];
      const bool valid = a == std::floor(a) && b == std::floor(b) && a >= 0 && b >= 0 && a < mics &&
                         b < mics && a != b;
      if (!valid) {
        reader.diagnostics().error(
            reader.path_of(mic_key),
            "two different mic indices in [0, " + std::to_string(mics - 1) + "] required");
        return;
      }
      ref.mic = static_cast<int>(a);
      ref.other_mic = static_cast<int>(b);
    } else {
      const std::optional<int> mic = reader.optional_integer(mic_key, 0, mics - 1);
      if (kind == MicRefKind::channel_delay) {
        // A channel's delay as a converter or buffer gives it: up to 10 ms either way.
        const std::optional<double> delay_s = reader.required_number("delay_s", -0.01, 0.01);
        if (!delay_s) return;
        ref.delay_s = *delay_s;
      }
      if (!mic) return;
      ref.mic = *mic;
    }
    if (array >= 0) out.push_back(ref);
  });
}

void parse_noise(ObjectReader& reader, Scenario& scenario) {
  NoiseSpec& noise = scenario.noise;
  parse_noise_level(reader, "sensor", noise.sensor);
  parse_noise_level(reader, "wind", noise.wind);
  parse_noise_level(reader, "ambient", noise.ambient);
  noise.wind_corner_hz = reader.number("wind_corner_hz", noise.wind_corner_hz, 1.0, 1000.0);
  noise.wind_gust_depth = reader.number("wind_gust_depth", noise.wind_gust_depth, 0.0, 1.0);
  noise.ambient_coherent_below_hz =
      reader.number("ambient_coherent_below_hz", 0.0, 0.0, 0.4 * scenario.sample_rate_hz);
  if (reader.has("impulsive")) {
    ObjectReader impulsive = reader.object("impulsive");
    ImpulsiveNoise& spec = noise.impulsive;
    const bool has_snr = impulsive.has("snr_db");
    const bool has_level = impulsive.has("level_db");
    if (has_snr == has_level)
      impulsive.diagnostics().error(impulsive.path(), "give exactly one of snr_db or level_db");
    if (has_snr) spec.snr_db = impulsive.required_number("snr_db", -60.0, 100.0);
    if (has_level) spec.level_db_spl = impulsive.required_number("level_db", -20.0, 160.0);
    spec.share = impulsive.number("share", spec.share, 0.0, 1.0);
    spec.burst_s = impulsive.number("burst_s", spec.burst_s, 1e-4, 10.0);
    spec.alpha = impulsive.number("alpha", spec.alpha, 0.1, 2.0);
    spec.per_channel = impulsive.boolean("per_channel", spec.per_channel);
    spec.enabled = spec.snr_db.has_value() || spec.level_db_spl.has_value();
  } else {
    reader.accept("impulsive");
  }
  noise.snr_reference_array = reader.string("snr_reference_array", "");
  if (!noise.snr_reference_array.empty() &&
      scenario.site.array_index(noise.snr_reference_array) < 0 && !scenario.site.arrays.empty()) {
    reader.diagnostics().error(reader.path_of("snr_reference_array"),
                               "no array with id \"" + noise.snr_reference_array + "\"");
  }
}

double largest_yaw_step_deg(const ArrayMotion& motion, double rate_hz, double duration_s) {
  double largest = 0.0;
  const auto lines = static_cast<std::size_t>(std::ceil(duration_s * rate_hz - 1e-9));
  double previous = motion.yaw_at_deg(0.0);
  for (std::size_t k = 1; k <= lines; ++k) {
    const double yaw = motion.yaw_at_deg(static_cast<double>(k) / rate_hz);
    largest = std::max(largest, std::abs(doa::wrap_deg_180(yaw - previous)));
    previous = yaw;
  }
  return largest;
}

// The simulator's keys of a moving array (taken out of `array` before the site parser sees it):
// trajectory, yaw ("heading" or "fixed"), pose_rate_hz; yaw_deg, pitch_deg and roll_deg are
// site keys, read here too. Fills in position_m (the trajectory at t = 0) if absent.
std::optional<MovingArray> parse_array_motion(json& array, const std::string& path,
                                              double duration_s, Diagnostics& diagnostics) {
  if (!array.contains("trajectory")) {
    for (const char* key : {"yaw", "pose_rate_hz"}) {
      if (!array.contains(key)) continue;
      diagnostics.error(path + "." + key, "only for a moving array (one with a trajectory)");
      array.erase(key);
    }
    return std::nullopt;
  }
  json keys = json::object();
  for (const char* key : {"trajectory", "yaw", "pose_rate_hz"}) {
    if (!array.contains(key)) continue;
    keys[key] = array[key];
    array.erase(key);
  }
  for (const char* key : {"yaw_deg", "pitch_deg", "roll_deg"}) {
    if (array.contains(key)) keys[key] = array[key];
  }
  const std::size_t errors_before = diagnostics.errors.size();
  ObjectReader reader(keys, path, diagnostics);
  MovingArray moving;
  std::optional<Trajectory> trajectory;
  {
    ObjectReader trajectory_reader = reader.object("trajectory");
    trajectory = parse_trajectory(trajectory_reader);
  }
  const std::string yaw = reader.choice("yaw", "heading", {"heading", "fixed"});
  moving.motion.yaw_mode = yaw == "heading" ? YawMode::heading : YawMode::fixed;
  moving.motion.yaw_deg = reader.number("yaw_deg", 0.0, -360.0, 360.0);
  moving.motion.pitch_deg = reader.number("pitch_deg", 0.0, -90.0, 90.0);
  moving.motion.roll_deg = reader.number("roll_deg", 0.0, -180.0, 180.0);
  moving.pose_rate_hz = reader.number("pose_rate_hz", moving.pose_rate_hz, 1.0, 1000.0);
  if (!trajectory || diagnostics.errors.size() != errors_before) {
    // The site parser would add "position_m missing" to the real problem.
    if (!array.contains("position_m")) array["position_m"] = {0.0, 0.0, 0.0};
    return std::nullopt;
  }
  moving.motion.trajectory = *trajectory;
  const Eigen::Vector3d start_m = trajectory->position(0.0);
  if (!array.contains("position_m")) {
    array["position_m"] = {start_m.x(), start_m.y(), start_m.z()};
  } else if (auto given =
                 config::read_vector3(array["position_m"], path + ".position_m", diagnostics)) {
    if ((*given - start_m).norm() > 1e-3) {
      std::ostringstream what;
      what << "differs from where the trajectory starts (" << start_m.x() << ", " << start_m.y()
           << ", " << start_m.z() << "); leave it out for a moving array";
      diagnostics.error(path + ".position_m", what.str());
      return std::nullopt;
    }
  }
  if (moving.motion.yaw_mode == YawMode::heading) {
    // The heading is undefined where the platform stops or climbs straight up.
    const auto samples = static_cast<std::size_t>(std::ceil(duration_s * 100.0)) + 1;
    for (std::size_t k = 0; k < samples; ++k) {
      const Eigen::Vector3d v = trajectory->at(static_cast<double>(k) / 100.0).velocity_mps;
      if (std::hypot(v.x(), v.y()) < 1e-3) {
        diagnostics.error(path + ".yaw",
                          "\"heading\" needs horizontal motion, but the array stands "
                          "still (or climbs vertically) at t = " +
                              config::format_number(static_cast<double>(k) / 100.0) +
                              " s; use \"fixed\"");
        return std::nullopt;
      }
    }
  }
  const double step_deg = largest_yaw_step_deg(moving.motion, moving.pose_rate_hz, duration_s);
  if (step_deg > kMaxPoseYawStep_deg) {
    diagnostics.error(path + ".pose_rate_hz",
                      "the array turns up to " + config::format_number(step_deg) +
                          " deg between pose lines at " +
                          config::format_number(moving.pose_rate_hz) + " Hz (at most " +
                          config::format_number(kMaxPoseYawStep_deg) + "); raise the rate");
    return std::nullopt;
  }
  return moving;
}

// The site section: validated by the site-config parser itself (so the simulator accepts exactly
// what replay will), with the simulator's own per-array keys (recording_end_s; a moving array's
// trajectory, yaw and pose_rate_hz) taken out first.
void parse_site(const json& node, const std::filesystem::path& base_dir, Scenario& scenario,
                Diagnostics& diagnostics) {
  if (!node.is_object()) {
    diagnostics.error("site", "expected an object (a site config, SPEC 3.1), got " +
                                  config::describe_json_type(node));
    return;
  }
  json site = node;
  if (site.contains("arrays") && site["arrays"].is_array()) {
    for (std::size_t i = 0; i < site["arrays"].size(); ++i) {
      json& array = site["arrays"][i];
      const std::string path = "site.arrays[" + std::to_string(i) + "]";
      double end_s = 0.0;
      if (array.is_object() && array.contains("recording_end_s")) {
        const json& value = array["recording_end_s"];
        if (!value.is_number() || !(value.get<double>() > 0.0)) {
          diagnostics.error(path + ".recording_end_s", "expected a number of seconds > 0");
        } else {
          end_s = value.get<double>();
        }
        array.erase("recording_end_s");
      }
      if (array.is_object() && array.contains("recording")) {
        diagnostics.warn(path + ".recording", "ignored: the simulator writes <id>.wav");
        array.erase("recording");
      }
      if (array.is_object() && array.contains("pose_file")) {
        diagnostics.warn(path + ".pose_file", "ignored: the simulator writes <id>.pose.jsonl");
        array.erase("pose_file");
      }
      scenario.recording_end_s.push_back(end_s);
      scenario.moving_arrays.push_back(
          array.is_object() ? parse_array_motion(array, path, scenario.duration_s, diagnostics)
                            : std::nullopt);
    }
  }
  scenario.site_json = site;
  std::vector<std::string> site_warnings;
  config::LoadOptions options;
  options.check_recordings = false;
  try {
    scenario.site = config::parse_site_config(site.dump(), base_dir, site_warnings, options);
  } catch (const config::ConfigError& failure) {
    for (const auto& problem : failure.problems()) diagnostics.errors.push_back("site." + problem);
  }
  for (const auto& warning : site_warnings) diagnostics.warnings.push_back("site." + warning);
}

}  // namespace

Scenario parse_scenario(const json& document, const std::filesystem::path& base_dir,
                        std::vector<std::string>& warnings) {
  Diagnostics diagnostics;
  Scenario scenario;
  {
    ObjectReader root(document, "", diagnostics);
    scenario.description = root.string("description", "");
    scenario.seed = static_cast<std::uint64_t>(root.integer("seed", 0, 0, 2147483647));
    // What replay takes (hydrophones sample at 100 kHz and more), no narrower.
    scenario.sample_rate_hz = root.number("sample_rate_hz", 48000.0, config::kMinSampleRate_hz,
                                          config::kMaxSampleRate_hz);
    scenario.duration_s = root.required_number("duration_s", 0.01, 3600.0).value_or(1.0);
    scenario.full_scale_db_spl = root.number("full_scale_db_spl", 120.0, 60.0, 200.0);
    {
      ObjectReader ground = root.object("ground");
      scenario.ground_reflection = ground.number("reflection_coefficient", 0.0, 0.0, 1.0);
    }
    root.accept("site");
    if (!root.has("site")) {
      diagnostics.error("site", "required site (arrays as in SPEC 3.1) is missing");
    } else {
      parse_site(document.at("site"), base_dir, scenario, diagnostics);
      for (std::size_t i = 0; i < scenario.recording_end_s.size(); ++i) {
        if (scenario.recording_end_s[i] > scenario.duration_s) {
          diagnostics.error("site.arrays[" + std::to_string(i) + "].recording_end_s",
                            "beyond duration_s");
        }
      }
    }
    std::set<std::string> ids;
    root.for_each("sources", true, [&](const json& node, const std::string& path) {
      ObjectReader reader(node, path, diagnostics);
      SourceSpec source;
      source.id = reader.required_string("id").value_or("");
      if (reader.has("id") && node["id"].is_string() && source.id.empty()) {
        diagnostics.error(reader.path_of("id"), "must not be empty");
      } else if (!source.id.empty() && !ids.insert(source.id).second) {
        diagnostics.error(reader.path_of("id"), "duplicate source id \"" + source.id + "\"");
      }
      const std::string kind = reader.choice("kind", "drone", {"drone", "interferer"});
      source.kind = kind == "drone" ? SourceKind::drone : SourceKind::interferer;
      source.source_class = reader.choice("class", kind == "drone" ? "drone" : "ground",
                                          {"drone", "ground", "aircraft", "bird"});
      if ((source.source_class == "drone") != (source.kind == SourceKind::drone))
        diagnostics.error(reader.path_of("class"),
                          "\"" + source.source_class + "\" does not fit kind \"" + kind + "\"");
      source.level_db_spl = reader.number("level_db", source.level_db_spl, 0.0, 160.0);
      {
        ObjectReader signal = reader.object("signal");
        parse_signal(signal, source, scenario.sample_rate_hz, base_dir);
      }
      if (!reader.has("trajectory")) {
        diagnostics.error(reader.path_of("trajectory"), "required trajectory is missing");
        reader.accept("trajectory");
      } else {
        ObjectReader trajectory = reader.object("trajectory");
        if (auto parsed = parse_trajectory(trajectory)) source.trajectory = *parsed;
      }
      scenario.sources.push_back(std::move(source));
    });
    if (root.has("sources") && document["sources"].is_array() && document["sources"].empty()) {
      diagnostics.error("sources", "at least one source is required");
    }
    {
      ObjectReader noise = root.object("noise");
      parse_noise(noise, scenario);
    }
    if (root.has("array_errors")) {
      ObjectReader errors = root.object("array_errors");
      ArrayErrorSpec& spec = scenario.array_error_spec;
      spec.enabled = true;
      spec.seed = static_cast<std::uint64_t>(
          errors.integer("seed", static_cast<int>(scenario.seed), 0, 2147483647));
      spec.mic_position_std_m = errors.number("mic_position_std_m", 0.0, 0.0, 0.1);
      spec.gain_spread_db = errors.number("gain_spread_db", 0.0, 0.0, 20.0);
      spec.channel_delay_std_s = errors.number("channel_delay_std_s", 0.0, 0.0, 0.01);
      spec.yaw_std_deg = errors.number("yaw_std_deg", 0.0, 0.0, 45.0);
      spec.tilt_std_deg = errors.number("tilt_std_deg", 0.0, 0.0, 45.0);
      spec.clock_offset_std_s = errors.number("clock_offset_std_s", 0.0, 0.0, 1.0);
      parse_mic_refs(errors, "dead_mics", scenario.site, spec.dead_mics);
      parse_mic_refs(errors, "flipped_mics", scenario.site, spec.flipped_mics);
      parse_mic_refs(errors, "swapped_channels", scenario.site, spec.swapped_channels,
                     MicRefKind::pair);
      parse_mic_refs(errors, "channel_delays", scenario.site, spec.channel_delays,
                     MicRefKind::channel_delay);
    }
    scenario.array_errors = draw_array_errors(scenario.array_error_spec, scenario.site);
    apply_geometry_errors(scenario.array_errors, scenario.site);
    if (root.has("reference_log")) {
      ObjectReader log = root.object("reference_log");
      ReferenceLogSpec& spec = scenario.reference_log;
      spec.enabled = true;
      spec.source = log.required_string("source").value_or("");
      spec.rate_hz = log.number("rate_hz", spec.rate_hz, 0.1, 1000.0);
      spec.position_std_m = log.number("position_std_m", spec.position_std_m, 0.0, 100.0);
      if (log.has("source") && !spec.source.empty() && !ids.contains(spec.source))
        diagnostics.error(log.path_of("source"), "no source with id \"" + spec.source + "\"");
    }
    const bool needs_drone = scenario.noise.sensor.snr_db || scenario.noise.wind.snr_db ||
                             scenario.noise.ambient.snr_db || scenario.noise.impulsive.snr_db;
    bool has_drone = false;
    for (const auto& source : scenario.sources) has_drone |= source.kind == SourceKind::drone;
    if (needs_drone && !has_drone && !scenario.sources.empty()) {
      diagnostics.error("noise", "snr_db is relative to the drones' sound, but there is no drone");
    }
  }
  warnings.insert(warnings.end(), diagnostics.warnings.begin(), diagnostics.warnings.end());
  if (!diagnostics.errors.empty()) throw config::ConfigError(std::move(diagnostics.errors));
  return scenario;
}

Scenario parse_scenario(const json& document, const std::filesystem::path& base_dir) {
  std::vector<std::string> warnings;
  return parse_scenario(document, base_dir, warnings);
}

Scenario load_scenario(const std::filesystem::path& file, std::vector<std::string>& warnings) {
  std::string text;
  try {
    text = read_text_file(file, config::kMaxConfigBytes, "scenario file");
  } catch (const std::runtime_error& failure) {
    throw config::ConfigError({failure.what()});
  }
  json document;
  try {
    document = json::parse(text);
  } catch (const json::exception& failure) {
    throw config::ConfigError({file.string() + ": invalid JSON: " + failure.what()});
  }
  std::vector<std::string> local_warnings;
  try {
    Scenario scenario = parse_scenario(document, file.parent_path(), local_warnings);
    scenario.file = file;
    for (const auto& warning : local_warnings) warnings.push_back(file.string() + ": " + warning);
    return scenario;
  } catch (const config::ConfigError& failure) {
    std::vector<std::string> problems;
    for (const auto& problem : failure.problems())
      problems.push_back(file.string() + ": " + problem);
    throw config::ConfigError(std::move(problems));
  }
}

}  // namespace dronetrack::sim
