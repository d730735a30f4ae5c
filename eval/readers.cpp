#include "eval/readers.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "common/input_file.hpp"
#include "config/config_reader.hpp"
#include "config/site_config.hpp"

namespace dronetrack::eval {
namespace {

using config::Diagnostics;
using config::ObjectReader;

std::string read_file(const std::filesystem::path& file, std::size_t max_bytes) {
  try {
    return read_text_file(file, max_bytes, "file");
  } catch (const std::runtime_error& error) {
    throw InputError(error.what());
  }
}

std::ifstream open_lines(const std::filesystem::path& file) {
  std::error_code error;
  if (std::filesystem::is_directory(file, error))
    throw InputError(file.string() + ": is a directory");
  std::ifstream stream(file, std::ios::binary);
  if (!stream) throw InputError(file.string() + ": cannot open for reading");
  return stream;
}

// The library's message without its "[json.exception.parse_error.101] parse error at ..."
// prefix: the reader says where.
std::string json_problem(const nlohmann::json::exception& error) {
  std::string what = error.what();
  const auto bracket = what.find("] ");
  if (bracket != std::string::npos) what = what.substr(bracket + 2);
  const auto colon = what.find(": ", what.find("parse error"));
  if (what.rfind("parse error", 0) == 0 && colon != std::string::npos)
    what = what.substr(colon + 2);
  return what;
}

// One line: the first problem, and how many more there were.
void throw_if_errors(const Diagnostics& diagnostics, const std::string& where) {
  if (diagnostics.errors.empty()) return;
  std::string message = where + ": " + diagnostics.errors.front();
  if (diagnostics.errors.size() > 1) {
    message += " (and " + std::to_string(diagnostics.errors.size() - 1) + " more problems)";
  }
  throw InputError(message);
}

nlohmann::json parse_document(const std::string& text, const std::string& where) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& error) {
    // Turn the byte offset into a line number; the library's message names the token.
    const std::size_t byte = std::min<std::size_t>(error.byte, text.size());
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<long>(byte), '\n');
    throw InputError(where + ":" + std::to_string(line) + ": invalid JSON: " + json_problem(error));
  } catch (const nlohmann::json::exception& error) {
    // A number that overflows a double (1e999) is not a parse_error.
    throw InputError(where + ": invalid JSON: " + json_problem(error));
  }
}

std::vector<Eigen::Vector3d> read_vectors(const nlohmann::json& node, const std::string& path,
                                          Diagnostics& diagnostics) {
  std::vector<Eigen::Vector3d> out;
  if (!node.is_array()) {
    diagnostics.error(path,
                      "expected a list of [x, y, z], got " + config::describe_json_type(node));
    return out;
  }
  out.reserve(node.size());
  for (std::size_t i = 0; i < node.size(); ++i) {
    const auto vector =
        config::read_vector3(node[i], path + "[" + std::to_string(i) + "]", diagnostics);
    if (!vector) return {};
    out.push_back(*vector);
  }
  return out;
}

TruthSource read_source(const nlohmann::json& node, const std::string& path,
                        Diagnostics& diagnostics) {
  TruthSource source;
  ObjectReader reader(node, path, diagnostics);
  source.id = reader.required_string("id").value_or("");
  for (const char* key : {"kind", "class", "velocity_mps"}) reader.accept(key);
  const std::size_t errors_before = diagnostics.errors.size();
  source.time_s = reader.numbers("t", 0, true).value_or(std::vector<double>{});
  for (std::size_t i = 1; i < source.time_s.size(); ++i) {
    if (!(source.time_s[i] > source.time_s[i - 1])) {
      diagnostics.error(reader.path_of("t") + "[" + std::to_string(i) + "]",
                        "times must be increasing");
      break;
    }
  }
  reader.accept("position_m");
  if (node.is_object() && node.contains("position_m")) {
    source.position_m = read_vectors(node["position_m"], reader.path_of("position_m"), diagnostics);
  } else {
    diagnostics.error(reader.path_of("position_m"), "required list is missing");
  }
  if (diagnostics.errors.size() == errors_before &&
      source.position_m.size() != source.time_s.size()) {
    diagnostics.error(reader.path_of("position_m"),
                      "has " + std::to_string(source.position_m.size()) + " rows but t has " +
                          std::to_string(source.time_s.size()));
  }
  reader.accept("doa");
  if (node.is_object() && node.contains("doa")) {
    const auto& doa = node["doa"];
    const std::string doa_path = reader.path_of("doa");
    if (!doa.is_object()) {
      diagnostics.error(doa_path, "expected an object keyed by array id");
    } else {
      for (const auto& [array, entry] : doa.items()) {
        ObjectReader array_reader(entry, doa_path + "." + array, diagnostics);
        array_reader.accept("direction");
        if (!entry.is_object() || !entry.contains("direction")) {
          diagnostics.error(array_reader.path_of("direction"), "required list is missing");
          continue;
        }
        auto directions =
            read_vectors(entry["direction"], array_reader.path_of("direction"), diagnostics);
        if (directions.size() != source.time_s.size()) {
          diagnostics.error(array_reader.path_of("direction"),
                            "has " + std::to_string(directions.size()) + " rows but t has " +
                                std::to_string(source.time_s.size()));
          continue;
        }
        source.direction_by_array[array] = std::move(directions);
      }
    }
  }
  return source;
}

// Reads every non-blank line as one JSON object; `fill` fills a record from its reader.
template <typename Record, typename Fill>
std::vector<Record> parse_lines(std::istream& stream, const std::string& file, Fill fill) {
  std::vector<Record> out;
  config::LineReader lines(stream, config::kMaxLineBytes);
  std::string line;
  while (lines.next(line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::string where = file + ":" + std::to_string(lines.number());
    nlohmann::json node;
    try {
      node = nlohmann::json::parse(line);
    } catch (const nlohmann::json::exception& error) {
      throw InputError(where + ": invalid JSON: " + json_problem(error));
    }
    Diagnostics diagnostics;
    Record record;
    {
      ObjectReader reader(node, "", diagnostics);
      fill(reader, node, diagnostics, record);
    }
    throw_if_errors(diagnostics, where);
    if constexpr (requires { record.line; }) record.line = lines.number();
    out.push_back(std::move(record));
  }
  if (lines.too_long()) {
    throw InputError(file + ":" + std::to_string(lines.number()) + ": line longer than " +
                     std::to_string(config::kMaxLineBytes) +
                     " bytes (a JSON line of this format is under 1 kB)");
  }
  if (stream.bad()) throw InputError(file + ": read error");
  return out;
}

template <typename Record, typename Fill>
std::vector<Record> parse_text_lines(const std::string& text, const std::string& file, Fill fill) {
  std::istringstream stream(text);
  return parse_lines<Record>(stream, file, fill);
}

template <typename Record, typename Fill>
std::vector<Record> read_file_lines(const std::filesystem::path& file, Fill fill) {
  std::ifstream stream = open_lines(file);
  return parse_lines<Record>(stream, file.string(), fill);
}

}  // namespace

Truth parse_truth(const std::string& text, const std::string& file) {
  const nlohmann::json document = parse_document(text, file);
  Diagnostics diagnostics;
  Truth truth;
  {
    ObjectReader reader(document, "", diagnostics);
    for (const char* key : {"rate_hz", "duration_s", "speed_of_sound_mps"}) {
      reader.accept(key);
    }
    reader.for_each("sources", true, [&](const nlohmann::json& node, const std::string& path) {
      truth.sources.push_back(read_source(node, path, diagnostics));
    });
    reader.for_each("interferers", false, [&](const nlohmann::json& node, const std::string& path) {
      truth.others.push_back(read_source(node, path, diagnostics));
      std::string source_class = "ground";
      if (node.is_object() && node.contains("class") && node["class"].is_string())
        source_class = node["class"].get<std::string>();
      truth.other_classes.push_back(source_class);
    });
    if (reader.has("arrays")) {
      ObjectReader arrays = reader.object("arrays");
      for (const auto& [id, entry] : document["arrays"].items()) {
        arrays.accept(id);
        ObjectReader array(entry, arrays.path_of(id), diagnostics);
        if (auto centre = array.vector3("centre_m", false)) truth.array_centres_m[id] = *centre;
        if (array.has("recording_end_s")) {
          const double end = array.number("recording_end_s", 0.0, 0.0);
          truth.recording_end_s =
              truth.recording_end_s ? std::min(*truth.recording_end_s, end) : end;
        }
      }
    }
  }
  throw_if_errors(diagnostics, file);
  if (truth.sources.empty()) throw InputError(file + ": sources: no drone in the truth");
  return truth;
}

namespace {
void fill_track(ObjectReader& reader, const nlohmann::json& node, Diagnostics& diagnostics,
                TrackRecord& record) {
  for (const char* key : {"velocity_mps", "acceleration_mps2", "covariance", "arrays",
                          "contributing_arrays", "hypotheses"}) {
    reader.accept(key);
  }
  (void)node;
  (void)diagnostics;
  record.time_s =
      reader.required_number("t", -kMaxAbsoluteTime_s, kMaxAbsoluteTime_s).value_or(0.0);
  if (reader.has("id")) {
    record.id = reader.integer("id", 0, -2147483647, 2147483647);
  } else {
    reader.diagnostics().error("id", "required integer is missing");
  }
  record.position_m = reader.vector3("position_m", true).value_or(Eigen::Vector3d::Zero());
  record.status = reader.choice("status", "confirmed", {"tentative", "confirmed", "coasting"});
  record.track_class =
      reader.choice("class", "unknown", {"drone", "ground", "aircraft", "unknown"});
  record.one_array = reader.boolean("one_array", false);
  if (reader.has("position_std_m")) {
    const auto std_m = reader.vector3("position_std_m", true);
    if (std_m && (std_m->array() >= 0.0).all()) {
      record.position_std_m = *std_m;
    } else if (std_m) {
      reader.diagnostics().error(reader.path_of("position_std_m"), "expected 3 numbers >= 0");
    }
  }
  // Extra keys are allowed in JSON lines.
  for (const auto& item : node.items()) reader.accept(item.key());
}

void fill_alert(ObjectReader& reader, const nlohmann::json& node, Diagnostics&,
                AlertRecord& record) {
  record.time_s =
      reader.required_number("t", -kMaxAbsoluteTime_s, kMaxAbsoluteTime_s).value_or(0.0);
  record.zone = reader.string("zone", "");
  record.track_id = reader.optional_integer("track_id", -2147483647, 2147483647).value_or(0);
  record.event = reader.choice("event", "entered", {"entered", "left", "class_changed"});
  for (const auto& item : node.items()) reader.accept(item.key());
}

// A unit vector within the writer's rounding, or an error at its key.
std::optional<Eigen::Vector3d> unit_vector(ObjectReader& reader, const std::string& key) {
  const auto vector = reader.vector3(key, true);
  if (!vector) return std::nullopt;
  if (std::abs(vector->norm() - 1.0) > 1e-3) {
    reader.diagnostics().error(reader.path_of(key), "expected a unit vector");
    return std::nullopt;
  }
  return vector->normalized();
}

// The issue-15 blocks of a DOA line: "pose", "cone", "mirror_normal" (docs/contract.md).
void fill_doa_geometry(ObjectReader& reader, Diagnostics& diagnostics, DoaRecord& record) {
  if (reader.has("pose")) {
    ObjectReader pose = reader.object("pose");
    DoaRecord::Pose value;
    value.centre_m = pose.vector3("centre_m", true).value_or(Eigen::Vector3d::Zero());
    if (const auto attitude = pose.numbers("attitude_deg", 3, true)) {
      value.attitude_deg = Eigen::Vector3d((*attitude)[0], (*attitude)[1], (*attitude)[2]);
      if (!(value.attitude_deg.cwiseAbs().maxCoeff() <= 360.0))
        diagnostics.error(pose.path_of("attitude_deg"), "expected angles within +-360 deg");
    }
    if (!(value.centre_m.cwiseAbs().maxCoeff() <= config::kMaxSiteCoordinate_m))
      diagnostics.error(pose.path_of("centre_m"), "beyond the site's coordinate bound");
    record.pose = value;
  }
  if (reader.has("cone")) {
    ObjectReader cone = reader.object("cone");
    DoaRecord::Cone value;
    value.axis = unit_vector(cone, "axis").value_or(Eigen::Vector3d::UnitX());
    value.angle_deg = cone.required_number("angle_deg", 0.0, 180.0).value_or(0.0);
    value.angle_std_deg = cone.required_number("angle_std_deg", 1e-9, 180.0).value_or(1.0);
    if (cone.has("peaks_deg") || cone.has("peak_weights")) {
      value.peaks_deg = cone.numbers("peaks_deg", 0, true).value_or(std::vector<double>{});
      value.peak_weights = cone.numbers("peak_weights", 0, true).value_or(std::vector<double>{});
      const bool sane = value.peaks_deg.size() == value.peak_weights.size() &&
                        value.peaks_deg.size() <= static_cast<std::size_t>(doa::kMaxConePeaks) &&
                        std::all_of(value.peaks_deg.begin(), value.peaks_deg.end(),
                                    [](double angle) { return angle >= 0.0 && angle <= 180.0; }) &&
                        std::all_of(value.peak_weights.begin(), value.peak_weights.end(),
                                    [](double weight) { return weight >= 0.0; });
      if (!sane) {
        diagnostics.error(cone.path_of("peaks_deg"),
                          "expected up to " + std::to_string(doa::kMaxConePeaks) +
                              " angles in [0, 180] deg with as many weights >= 0");
      }
    }
    record.cone = value;
    if (record.ambiguity != "cone") diagnostics.error("cone", "only a cone DOA carries one");
  } else if (record.ambiguity == "cone") {
    diagnostics.error("cone",
                      "a cone DOA must say what it measured (axis, angle_deg, "
                      "angle_std_deg)");
  }
  if (reader.has("mirror_normal")) {
    record.mirror_normal = unit_vector(reader, "mirror_normal");
    if (record.ambiguity != "mirror_up_down")
      diagnostics.error("mirror_normal", "only a mirror_up_down DOA carries one");
  }
}

void fill_doa(ObjectReader& reader, const nlohmann::json& node, Diagnostics& diagnostics,
              DoaRecord& record) {
  record.time_s =
      reader.required_number("t", -kMaxAbsoluteTime_s, kMaxAbsoluteTime_s).value_or(0.0);
  record.array = reader.required_string("array").value_or("");
  record.direction = reader.vector3("direction", true).value_or(Eigen::Vector3d::UnitX());
  if (!(record.direction.norm() > 0.5)) {
    diagnostics.error("direction", "expected a unit vector");
  }
  record.source_index = reader.integer("source", 0, 0, 1000);
  record.quality = reader.number("quality", 0.0);
  record.snr_db = reader.number("snr_db", 0.0);
  record.ambiguity = reader.choice("ambiguity", "none", {"none", "mirror_up_down", "cone"});
  if (const auto std_deg = reader.numbers("azel_std_deg", 2, false)) {
    if ((*std_deg)[0] > 0.0 && (*std_deg)[1] > 0.0) {
      record.azel_std_deg = Eigen::Vector2d((*std_deg)[0], (*std_deg)[1]);
    } else {
      diagnostics.error("azel_std_deg", "expected two positive numbers");
    }
  }
  record.azel_correlation = reader.number("azel_correlation", 0.0, -1.0, 1.0);
  if (reader.has("acoustic")) {
    ObjectReader acoustic = reader.object("acoustic");
    doa::AcousticFeatures& a = record.acoustic;
    a.valid = true;
    a.fundamental_hz = acoustic.number("fundamental_hz", 0.0, 0.0, 1e5);
    a.comb_strength = acoustic.number("comb_strength", 0.0, 0.0, 1.0);
    a.harmonic_count = acoustic.integer("harmonics", 0, 0, 100000);
    a.broadband_share = acoustic.number("broadband_share", 1.0, 0.0, 1.0);
    a.comb_persistence = acoustic.number("comb_persistence", 0.0, 0.0, 1.0);
    a.fundamental_spread = acoustic.number("fundamental_spread", 0.0, 0.0, 1e3);
    a.level_modulation_db = acoustic.number("level_modulation_db", 0.0, 0.0, 1e3);
    a.history_s = acoustic.number("history_s", 0.0, 0.0, 1e6);
  }
  fill_doa_geometry(reader, diagnostics, record);
  for (const auto& item : node.items()) reader.accept(item.key());
}
}  // namespace

std::vector<TrackRecord> parse_tracks(const std::string& text, const std::string& file) {
  return parse_text_lines<TrackRecord>(text, file, fill_track);
}
std::vector<AlertRecord> parse_alerts(const std::string& text, const std::string& file) {
  return parse_text_lines<AlertRecord>(text, file, fill_alert);
}
std::vector<DoaRecord> parse_doas(const std::string& text, const std::string& file) {
  return parse_text_lines<DoaRecord>(text, file, fill_doa);
}

Truth read_truth(const std::filesystem::path& file) {
  return parse_truth(read_file(file, config::kMaxTruthBytes), file.string());
}
std::vector<TrackRecord> read_tracks(const std::filesystem::path& file) {
  return read_file_lines<TrackRecord>(file, fill_track);
}
std::vector<AlertRecord> read_alerts(const std::filesystem::path& file) {
  return read_file_lines<AlertRecord>(file, fill_alert);
}
std::vector<DoaRecord> read_doas(const std::filesystem::path& file) {
  return read_file_lines<DoaRecord>(file, fill_doa);
}

}  // namespace dronetrack::eval
