#include "config/site_config.hpp"

#include <cctype>
#include <fstream>
#include <set>
#include <sstream>

#include "capture/recording_info.hpp"
#include "common/input_file.hpp"
#include "config/config_reader.hpp"
#include "config/parse_sections.hpp"
#include "config/pose_file.hpp"
#include "doa/ls_doa_solver.hpp"
#include "doa/node_pipeline.hpp"

namespace dronetrack::config {
namespace {

constexpr const char* kSiteExtentReason =
    "a coordinate beyond 100 km of the site origin (acoustic range is a few km; metres?)";
// A mic belongs to its array: the far-field model holds over a few metres, not a kilometre.
constexpr double kMaxMicOffset_m = 100.0;
// A calibration's corrections: a channel later than 0.1 s or 40 dB off is a broken channel, and a
// node clock an hour off is a wrong time zone, not a drift.
constexpr double kMaxChannelDelay_s = 0.1;
constexpr double kMaxChannelGain_db = 40.0;
constexpr double kMaxClockOffset_s = 3600.0;
// A zone smaller than this cannot be entered by a track with metre-level error.
constexpr double kMinZoneArea_m2 = 1.0;

std::string join_lines(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& line : lines) out += (out.empty() ? "" : "\n") + line;
  return out;
}

void parse_mics(const nlohmann::json& node, const std::string& path, Diagnostics& diagnostics,
                std::vector<Eigen::Vector3d>& mics) {
  if (!node.is_array()) {
    diagnostics.error(path, "expected a list of [x, y, z], got " + describe_json_type(node));
    return;
  }
  for (std::size_t i = 0; i < node.size(); ++i) {
    if (auto mic = read_vector3(node[i], path + "[" + std::to_string(i) + "]", diagnostics)) {
      mics.push_back(*mic);
    }
  }
  if (mics.size() != node.size()) return;
  if (mics.size() < 2) {
    diagnostics.error(path, "an array needs at least 2 mics, got " + std::to_string(mics.size()));
    return;
  }
  for (std::size_t i = 0; i < mics.size(); ++i) {
    if (mics[i].norm() > kMaxMicOffset_m) {
      diagnostics.error(path + "[" + std::to_string(i) + "]",
                        "mic " + format_number(mics[i].norm()) +
                            " m from its array's centre; at most " +
                            format_number(kMaxMicOffset_m) + " m (one array is one place)");
      return;
    }
  }
  constexpr double kMinSpacing_m = 1e-3;
  for (std::size_t i = 0; i < mics.size(); ++i) {
    for (std::size_t j = i + 1; j < mics.size(); ++j) {
      if ((mics[i] - mics[j]).norm() < kMinSpacing_m) {
        diagnostics.error(path, "mics " + std::to_string(i) + " and " + std::to_string(j) +
                                    " coincide (closer than 1 mm)");
      }
    }
  }
}

ArrayConfig parse_array(const nlohmann::json& node, const std::string& path,
                        const std::filesystem::path& base_dir, bool read_pose_files,
                        Diagnostics& diagnostics) {
  ArrayConfig array;
  ObjectReader reader(node, path, diagnostics);
  array.geometry.id = reader.required_string("id").value_or("");
  if (reader.has("id") && array.geometry.id.empty()) {
    diagnostics.error(reader.path_of("id"), "must not be empty");
  }
  if (array.geometry.id.size() > 64) {
    diagnostics.error(reader.path_of("id"), "longer than 64 characters");
  }
  // Ids become DDS keys, JSON strings and file names: keep them plain.
  for (char character : array.geometry.id) {
    if (!std::isalnum(static_cast<unsigned char>(character)) && character != '_' &&
        character != '-' && character != '.') {
      diagnostics.error(reader.path_of("id"),
                        "\"" + array.geometry.id + "\": use only letters, digits, '_', '-' or '.'");
      break;
    }
  }
  if (auto position = reader.vector3("position_m", true)) {
    array.geometry.position_m = *position;
    if (position->cwiseAbs().maxCoeff() > kMaxSiteCoordinate_m)
      diagnostics.error(reader.path_of("position_m"), kSiteExtentReason);
  }
  array.geometry.yaw_deg = reader.number("yaw_deg", 0.0, -360.0, 360.0);
  array.geometry.pitch_deg = reader.number("pitch_deg", 0.0, -90.0, 90.0);
  array.geometry.roll_deg = reader.number("roll_deg", 0.0, -180.0, 180.0);
  array.geometry.mic_position_std_m = reader.number("mic_position_std_m", 0.0, 0.0, 1.0);
  reader.accept("mics_m");
  if (!reader.has("mics_m")) {
    diagnostics.error(reader.path_of("mics_m"), "required list of mic positions is missing");
  } else {
    parse_mics(node.at("mics_m"), reader.path_of("mics_m"), diagnostics, array.geometry.mics_m);
  }
  // A site calibration's results (docs/calibration.md): one value per mic, each within a bound.
  const auto per_mic = [&](const std::string& key, double bound, std::vector<double>& target) {
    const auto values = reader.numbers(key, 0, false);
    if (!values) return;
    const std::size_t mics = array.geometry.mics_m.size();
    if (mics > 0 && values->size() != mics) {
      diagnostics.error(reader.path_of(key), "has " + std::to_string(values->size()) +
                                                 " entries for " + std::to_string(mics) + " mics");
      return;
    }
    for (std::size_t i = 0; i < values->size(); ++i) {
      if (std::abs((*values)[i]) > bound)
        diagnostics.error(
            reader.path_of(key) + "[" + std::to_string(i) + "]",
            "must be within +-" + format_number(bound) + ", got " + format_number((*values)[i]));
    }
    target = *values;
  };
  per_mic("channel_delay_s", kMaxChannelDelay_s, array.geometry.channel_delay_s);
  per_mic("channel_gain_db", kMaxChannelGain_db, array.geometry.channel_gain_db);
  array.geometry.clock_offset_s =
      reader.number("clock_offset_s", 0.0, -kMaxClockOffset_s, kMaxClockOffset_s);
  const std::string recording = reader.string("recording", "");
  if (!recording.empty()) {
    const std::filesystem::path recording_path(recording);
    array.recording = recording_path.is_absolute() ? recording_path : base_dir / recording_path;
  }
  array.pose_max_gap_s = reader.number("pose_max_gap_s", 1.0, 1e-3, 60.0);
  array.pose_topic = reader.boolean("pose_topic", false);
  const std::string pose_file = reader.string("pose_file", "");
  if (reader.has("pose_file") && pose_file.empty())
    diagnostics.error(reader.path_of("pose_file"), "must not be empty");
  if (!pose_file.empty()) {
    const std::filesystem::path pose_path(pose_file);
    array.pose_file = pose_path.is_absolute() ? pose_path : base_dir / pose_path;
  }
  if (!array.pose_file.empty() && read_pose_files) {
    PoseFileLimits limits;
    limits.max_gap_s = array.pose_max_gap_s;
    limits.max_coordinate_m = kMaxSiteCoordinate_m;
    limits.max_gap_key = reader.path_of("pose_max_gap_s");
    try {
      array.pose = read_pose_file(array.pose_file, limits);
    } catch (const std::exception& failure) {
      diagnostics.error(reader.path_of("pose_file"), failure.what());
    }
  }
  array.device = reader.optional_integer("device", 0, 100000);
  if (reader.has("ground_height_m"))
    array.ground_height_m = reader.number("ground_height_m", 0.0, -10000.0, 10000.0);
  if (auto map = reader.numbers("channel_map", 0, false)) {
    std::set<int> seen;
    for (std::size_t i = 0; i < map->size(); ++i) {
      const double channel = (*map)[i];
      const std::string element_path =
          reader.path_of("channel_map") + "[" + std::to_string(i) + "]";
      if (channel < 0 || channel > 1023 || channel != static_cast<int>(channel)) {
        diagnostics.error(element_path, "expected a channel index >= 0");
      } else if (!seen.insert(static_cast<int>(channel)).second) {
        diagnostics.error(element_path, "channel " + std::to_string(static_cast<int>(channel)) +
                                            " is mapped twice");
      } else {
        array.channel_map.push_back(static_cast<int>(channel));
      }
    }
    if (!array.geometry.mics_m.empty() && map->size() != array.geometry.mics_m.size()) {
      diagnostics.error(reader.path_of("channel_map"),
                        "has " + std::to_string(map->size()) + " entries for " +
                            std::to_string(array.geometry.mics_m.size()) + " mics");
    }
  }
  if (array.channel_map.empty()) {
    for (std::size_t i = 0; i < array.geometry.mics_m.size(); ++i) {
      array.channel_map.push_back(static_cast<int>(i));
    }
  }
  return array;
}

// Sample rates are whole numbers of hertz: print all their digits (2147483647, not 2.14748e+09).
std::string hertz_text(double rate_hz) { return std::to_string(static_cast<long long>(rate_hz)); }

void check_recording(const ArrayConfig& array, const std::string& path, bool explicit_map,
                     double band_high_hz, const doa::DoaParams& params, double speed_of_sound_mps,
                     Diagnostics& diagnostics) {
  capture::RecordingInfo info;
  try {
    info = capture::probe_recording(array.recording);
  } catch (const std::exception& failure) {
    diagnostics.error(path + ".recording", failure.what());
    return;
  }
  const int mics = static_cast<int>(array.geometry.mics_m.size());
  if (!explicit_map && info.channels != mics) {
    diagnostics.error(path + ".recording",
                      array.recording.string() + " has " + std::to_string(info.channels) +
                          " channels but the array has " + std::to_string(mics) + " mics");
  }
  if (explicit_map) {
    for (std::size_t mic = 0; mic < array.channel_map.size(); ++mic) {
      if (array.channel_map[mic] >= info.channels) {
        diagnostics.error(path + ".channel_map[" + std::to_string(mic) + "]",
                          "channel " + std::to_string(array.channel_map[mic]) +
                              " does not exist in " + array.recording.string() + " (" +
                              std::to_string(info.channels) + " channels)");
      }
    }
  }
  if (!(info.sample_rate_hz >= kMinSampleRate_hz && info.sample_rate_hz <= kMaxSampleRate_hz)) {
    diagnostics.error(path + ".recording", array.recording.string() + ": sample rate " +
                                               hertz_text(info.sample_rate_hz) +
                                               " Hz; dronetrack takes " +
                                               format_number(kMinSampleRate_hz) + " to " +
                                               format_number(kMaxSampleRate_hz) + " Hz");
    return;
  }
  if (info.sample_rate_hz / 2.0 < band_high_hz) {
    diagnostics.error(path + ".recording",
                      array.recording.string() + ": sample rate " +
                          hertz_text(info.sample_rate_hz) +
                          " Hz puts the Nyquist frequency below the band's upper edge (" +
                          format_number(band_high_hz) + " Hz)");
    return;
  }
  const std::string problem = doa::NodePipeline::setup_problem(
      array.geometry, params, info.sample_rate_hz, speed_of_sound_mps);
  if (!problem.empty()) {
    diagnostics.error(path, "with " + array.recording.string() + " (" +
                                hertz_text(info.sample_rate_hz) + " Hz): " + problem);
  }
}

void parse_zone(const nlohmann::json& node, const std::string& path, Diagnostics& diagnostics,
                std::vector<fusion::Zone>& zones) {
  ObjectReader reader(node, path, diagnostics);
  fusion::Zone zone;
  zone.name = reader.required_string("name").value_or("");
  reader.for_each(
      "polygon_m", true, [&](const nlohmann::json& vertex, const std::string& vertex_path) {
        if (!vertex.is_array() || vertex.size() != 2 || !vertex[0].is_number() ||
            !vertex[1].is_number()) {
          diagnostics.error(vertex_path,
                            "expected 2 numbers [x, y], got " + describe_json_type(vertex));
          return;
        }
        zone.polygon_m.emplace_back(vertex[0].get<double>(), vertex[1].get<double>());
      });
  if (reader.has("polygon_m") && zone.polygon_m.size() < 3) {
    diagnostics.error(reader.path_of("polygon_m"), "a zone needs at least 3 vertices");
  } else if (zone.polygon_m.size() >= 3) {
    double twice_area = 0.0;
    bool inside_site = true;
    for (std::size_t i = 0; i < zone.polygon_m.size(); ++i) {
      const Eigen::Vector2d& a = zone.polygon_m[i];
      const Eigen::Vector2d& b = zone.polygon_m[(i + 1) % zone.polygon_m.size()];
      twice_area += a.x() * b.y() - b.x() * a.y();
      inside_site = inside_site && a.cwiseAbs().maxCoeff() <= kMaxSiteCoordinate_m;
    }
    if (!inside_site) {
      diagnostics.error(reader.path_of("polygon_m"), kSiteExtentReason);
    } else if (std::abs(0.5 * twice_area) < kMinZoneArea_m2) {
      diagnostics.error(reader.path_of("polygon_m"),
                        "encloses " + format_number(std::abs(0.5 * twice_area)) +
                            " m^2; a zone needs at least 1 m^2 (collinear or repeated vertices?)");
    }
  }
  if (auto band = reader.numbers("altitude_m", 2, false)) {
    zone.altitude_min_m = (*band)[0];
    zone.altitude_max_m = (*band)[1];
    if (zone.altitude_min_m >= zone.altitude_max_m) {
      diagnostics.error(reader.path_of("altitude_m"), "expected [min, max] with min < max");
    }
  }
  for (const auto& other : zones) {
    if (other.name == zone.name && !zone.name.empty()) {
      diagnostics.error(reader.path_of("name"), "duplicate zone name \"" + zone.name + "\"");
    }
  }
  zones.push_back(std::move(zone));
}

}  // namespace

ConfigError::ConfigError(std::vector<std::string> problems)
    : std::runtime_error(join_lines(problems)), problems_(std::move(problems)) {}

std::vector<doa::ArrayGeometry> SiteConfig::geometries() const {
  std::vector<doa::ArrayGeometry> out;
  for (const auto& array : arrays) out.push_back(array.geometry);
  return out;
}

int SiteConfig::array_index(const std::string& id) const {
  for (std::size_t i = 0; i < arrays.size(); ++i) {
    if (arrays[i].geometry.id == id) return static_cast<int>(i);
  }
  return -1;
}

SiteConfig parse_site_config(const std::string& json_text, const std::filesystem::path& base_dir,
                             std::vector<std::string>& warnings, const LoadOptions& options) {
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(json_text);
  } catch (const nlohmann::json::exception& failure) {
    // Syntax errors and numbers that overflow a double (1e999) both land here.
    throw ConfigError({std::string("invalid JSON: ") + failure.what()});
  }
  Diagnostics diagnostics;
  SiteConfig site;
  {
    ObjectReader root(document, "", diagnostics);
    site.speed_of_sound_mps = root.number("speed_of_sound_mps", 343.0, 100.0, 2000.0);
    std::set<std::string> ids;
    if (document.is_object() && document.contains("arrays") && document["arrays"].is_array() &&
        document["arrays"].size() > kMaxArrays) {
      // Before parsing any: each array becomes a node with FFT plans and buffers.
      diagnostics.error("arrays", "at most " + std::to_string(kMaxArrays) +
                                      " arrays (the fusion keeps a 64-bit mask of the arrays "
                                      "behind each track), got " +
                                      std::to_string(document["arrays"].size()));
      throw ConfigError(std::move(diagnostics.errors));
    }
    // One array is enough when the fusion may start tracks from one array (issue 15).
    const auto single_array_start = [&document] {
      if (!document.contains("fusion") || !document["fusion"].is_object()) return false;
      const nlohmann::json& fusion = document["fusion"];
      return fusion.contains("single_array_start") && fusion["single_array_start"].is_boolean() &&
             fusion["single_array_start"].get<bool>();
    };
    if (options.for_fusion && document.is_object() && document.contains("arrays") &&
        document["arrays"].is_array() && document["arrays"].size() == 1 && !single_array_start()) {
      diagnostics.error("arrays",
                        "the fusion needs at least 2 arrays (it triangulates), got 1 (or "
                        "fusion.single_array_start: true)");
    }
    root.for_each("arrays", true, [&](const nlohmann::json& node, const std::string& path) {
      ArrayConfig array = parse_array(node, path, base_dir, options.read_pose_files, diagnostics);
      if (!array.geometry.id.empty() && !ids.insert(array.geometry.id).second) {
        diagnostics.error(path + ".id", "duplicate array id \"" + array.geometry.id + "\"");
      }
      site.arrays.push_back(std::move(array));
    });
    if (root.has("arrays") && document["arrays"].is_array() && document["arrays"].empty()) {
      diagnostics.error("arrays", "at least one array is required");
    }
    {
      ObjectReader doa_section = root.object("doa");
      parse_doa_params(doa_section, site.doa);
    }
    if (site.doa.ground_echo) {
      // The echo model mirrors each mic in the ground: a mic at or under it has no mirror. Only
      // solid (3-D) arrays model the echo (a pair or a planar array cannot tell it from the
      // source), so a hydrophone pair under the surface is fine.
      for (std::size_t i = 0; i < site.arrays.size(); ++i) {
        if (doa::direction_rank(site.arrays[i].geometry.mics_m) < 3) continue;
        const std::string array_path = "arrays[" + std::to_string(i) + "]";
        const double ground_m = site.doa_params(i).ground_height_m;
        const std::string ground_key = site.arrays[i].ground_height_m
                                           ? array_path + ".ground_height_m"
                                           : std::string("doa.ground_height_m");
        for (std::size_t mic = 0; mic < site.arrays[i].geometry.mic_count(); ++mic) {
          const double z = site.arrays[i].geometry.mic_site_m(mic).z();
          if (z <= ground_m)
            diagnostics.error(array_path + ".mics_m[" + std::to_string(mic) + "]",
                              "mic at site z " + format_number(z) + " m is not above the ground (" +
                                  ground_key + " " + format_number(ground_m) +
                                  "); raise it, or set doa.ground_echo false");
        }
      }
    }
    {
      ObjectReader fusion_section = root.object("fusion");
      parse_fusion_params(fusion_section, site.fusion);
    }
    root.for_each("zones", false, [&](const nlohmann::json& node, const std::string& path) {
      parse_zone(node, path, diagnostics, site.zones);
    });
    {
      ObjectReader alerts = root.object("alerts");
      if (alerts.has("classes")) {
        site.alerts.classes.clear();
        alerts.for_each("classes", false, [&](const nlohmann::json& node, const std::string& path) {
          const auto track_class = node.is_string()
                                       ? fusion::track_class_from_string(node.get<std::string>())
                                       : std::nullopt;
          if (!track_class) {
            diagnostics.error(path,
                              "expected one of \"drone\", \"ground\", \"aircraft\", "
                              "\"unknown\", got " +
                                  node.dump());
            return;
          }
          site.alerts.classes.push_back(*track_class);
        });
      }
      site.alerts.min_confirmed_s =
          alerts.number("min_confirmed_s", site.alerts.min_confirmed_s, 0.0, 3600.0);
    }
    {
      ObjectReader dds = root.object("dds");
      site.dds.domain_id = dds.integer("domain_id", 0, 0, 232);
      if (dds.has("security")) {
        ObjectReader security = dds.object("security");
        const std::string directory = security.string("directory", "");
        if (directory.empty()) {
          diagnostics.error(security.path_of("directory"),
                            "the PKI directory made by scripts/site-pki.sh is required");
        } else {
          const std::filesystem::path path(directory);
          site.dds.security_directory = path.is_absolute() ? path : base_dir / path;
        }
      }
    }
    {
      ObjectReader http = root.object("http");
      site.http.bind = http.string("bind", site.http.bind);
      const auto file_key = [&](const char* key, std::filesystem::path& out) {
        const std::string text = http.string(key, "");
        if (http.has(key) && text.empty())
          diagnostics.error(http.path_of(key), "must not be empty");
        if (text.empty()) return;
        const std::filesystem::path file(text);
        out = file.is_absolute() ? file : base_dir / file;
      };
      file_key("tls_certificate", site.http.tls_certificate);
      file_key("tls_private_key", site.http.tls_private_key);
      file_key("users_file", site.http.users_file);
      if (site.http.tls_certificate.empty() != site.http.tls_private_key.empty()) {
        diagnostics.error(
            http.path_of(site.http.tls_certificate.empty() ? "tls_certificate" : "tls_private_key"),
            "tls_certificate and tls_private_key go together");
      }
    }
    {
      ObjectReader incident = root.object("incident");
      const std::string directory = incident.string("directory", "");
      if (incident.has("directory") && directory.empty())
        diagnostics.error(incident.path_of("directory"), "must not be empty");
      if (!directory.empty()) {
        const std::filesystem::path path(directory);
        site.incident.directory = path.is_absolute() ? path : base_dir / path;
      }
      IncidentConfig& clips = site.incident;
      clips.ring_s = incident.number("ring_s", clips.ring_s, 1.0, 86400.0);
      clips.before_s = incident.number("before_s", clips.before_s, 0.0, 3600.0);
      clips.after_s = incident.number("after_s", clips.after_s, 0.0, 3600.0);
      if (clips.ring_s < clips.before_s + clips.after_s + kIncidentAlertDelay_s)
        diagnostics.error(
            incident.path_of("ring_s"),
            format_number(clips.ring_s) + " s cannot hold a clip of before_s + " + "after_s = " +
                format_number(clips.before_s + clips.after_s) + " s and the alert's delay (" +
                format_number(kIncidentAlertDelay_s) + " s); make it at least " +
                format_number(clips.before_s + clips.after_s + kIncidentAlertDelay_s));
    }
    root.accept("description");
  }
  if (diagnostics.errors.empty() && options.check_recordings) {
    double band_high_hz = 0.0;
    for (const auto& band : site.doa.bands_hz) band_high_hz = std::max(band_high_hz, band.high_hz);
    for (std::size_t i = 0; i < site.arrays.size(); ++i) {
      const std::string path = "arrays[" + std::to_string(i) + "]";
      if (site.arrays[i].recording.empty()) {
        diagnostics.error(path + ".recording", "no recording given (needed for replay)");
        continue;
      }
      const bool explicit_map = document["arrays"][i].contains("channel_map");
      check_recording(site.arrays[i], path, explicit_map, band_high_hz, site.doa_params(i),
                      site.speed_of_sound_mps, diagnostics);
    }
  }
  warnings.insert(warnings.end(), diagnostics.warnings.begin(), diagnostics.warnings.end());
  if (!diagnostics.errors.empty()) throw ConfigError(std::move(diagnostics.errors));
  return site;
}

doa::DoaParams SiteConfig::doa_params(std::size_t array) const {
  doa::DoaParams params = doa;
  if (array < arrays.size() && arrays[array].ground_height_m)
    params.ground_height_m = *arrays[array].ground_height_m;
  return params;
}

SiteConfig load_site_config(const std::filesystem::path& file, std::vector<std::string>& warnings,
                            const LoadOptions& options) {
  std::string text;
  try {
    text = read_text_file(file, kMaxConfigBytes, "site config");
  } catch (const std::runtime_error& failure) {
    throw ConfigError({failure.what()});
  }
  std::vector<std::string> local_warnings;
  try {
    SiteConfig site = parse_site_config(text, file.parent_path(), local_warnings, options);
    site.file = file;
    for (const auto& warning : local_warnings) warnings.push_back(file.string() + ": " + warning);
    return site;
  } catch (const ConfigError& failure) {
    std::vector<std::string> problems;
    for (const auto& problem : failure.problems())
      problems.push_back(file.string() + ": " + problem);
    throw ConfigError(std::move(problems));
  }
}

}  // namespace dronetrack::config
