#include "apps/calibration_inputs.hpp"

#include <cmath>
#include <fstream>
#include <numbers>

#include <nlohmann/json.hpp>

#include "apps/commands.hpp"
#include "calib/tdoa_model.hpp"
#include "config/config_reader.hpp"

namespace dronetrack::apps {
namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;
// Times are stream seconds (or UNIX seconds); beyond this a double no longer resolves a
// microsecond and the value is a bug.
constexpr double kMaxTime_s = 1e10;

// Calls `each(node, where)` for every non-blank line of `file` parsed as JSON.
template <class Each>
void for_each_json_line(const std::filesystem::path& file, const std::string& what, Each each) {
  std::error_code error;
  if (std::filesystem::is_directory(file, error))
    throw UserError(file.string() + ": is a directory, not " + what);
  std::ifstream stream(file, std::ios::binary);
  if (!stream) throw UserError(file.string() + ": cannot open for reading");
  config::LineReader lines(stream, config::kMaxLineBytes);
  std::string line;
  while (lines.next(line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::string where = file.string() + ":" + std::to_string(lines.number());
    nlohmann::json node;
    try {
      node = nlohmann::json::parse(line);
    } catch (const nlohmann::json::exception&) {
      throw UserError(where + ": not valid JSON (" + what + "; NaN is not a JSON number)");
    }
    each(node, where);
  }
  if (lines.too_long())
    throw UserError(file.string() + ":" + std::to_string(lines.number()) + ": line longer than " +
                    std::to_string(config::kMaxLineBytes) + " bytes");
  if (stream.bad()) throw UserError(file.string() + ": read error");
}

void throw_first(const config::Diagnostics& diagnostics, const std::string& where) {
  if (!diagnostics.errors.empty()) throw UserError(where + ": " + diagnostics.errors.front());
}

}  // namespace

ReferenceLog read_reference_log(const std::filesystem::path& file) {
  ReferenceLog log;
  for_each_json_line(
      file, "a reference line {\"t\": s, \"position_m\": [x, y, z]}",
      [&](const nlohmann::json& node, const std::string& where) {
        config::Diagnostics diagnostics;
        calib::ReferenceSample sample;
        {
          config::ObjectReader reader(node, "", diagnostics);
          sample.time_s = reader.required_number("t", -kMaxTime_s, kMaxTime_s).value_or(0.0);
          sample.position_m = reader.vector3("position_m", true).value_or(Eigen::Vector3d::Zero());
          if (reader.has("position_std_m")) {
            const double std_m = reader.number("position_std_m", 0.0, 0.0, 1000.0);
            log.position_std_m = std::max(log.position_std_m.value_or(0.0), std_m);
          }
        }
        throw_first(diagnostics, where);
        if (!log.samples.empty() && !(sample.time_s > log.samples.back().time_s)) {
          throw UserError(where + ": t " + config::format_number(sample.time_s) +
                          " s is not after the previous line's " +
                          config::format_number(log.samples.back().time_s) + " s");
        }
        log.samples.push_back(sample);
      });
  if (log.samples.size() < 2)
    throw UserError(file.string() + ": " + std::to_string(log.samples.size()) +
                    " reference positions; a track needs at least 2");
  return log;
}

TdoaLine tdoa_line_of(const doa::DoaMeasurement& doa) {
  TdoaLine line;
  line.array = doa.array_index;
  line.time_s = doa.time_s;
  line.source = doa.source_index;
  line.direction = doa.direction;
  line.tdoa_s.assign(doa.tdoa_s.begin(), doa.tdoa_s.begin() + doa.pair_count);
  return line;
}

std::vector<TdoaLine> read_tdoa_lines(const std::filesystem::path& file,
                                      const config::SiteConfig& site) {
  std::vector<TdoaLine> out;
  for_each_json_line(
      file, "a TDOA line of replay --tdoa-out",
      [&](const nlohmann::json& node, const std::string& where) {
        config::Diagnostics diagnostics;
        TdoaLine line;
        std::string id;
        {
          config::ObjectReader reader(node, "", diagnostics);
          line.time_s = reader.required_number("t", -kMaxTime_s, kMaxTime_s).value_or(0.0);
          id = reader.required_string("array").value_or("");
          line.source = reader.integer("source", 0, 0, 64);
          line.direction = reader.vector3("direction", true).value_or(Eigen::Vector3d::UnitX());
          line.tdoa_s = reader.numbers("tdoa_s", 0, true).value_or(std::vector<double>{});
        }
        throw_first(diagnostics, where);
        line.array = site.array_index(id);
        if (line.array < 0) throw UserError(where + ": array \"" + id + "\" is not in the site");
        const std::size_t mics =
            site.arrays[static_cast<std::size_t>(line.array)].geometry.mic_count();
        if (line.tdoa_s.size() != mics * (mics - 1) / 2)
          throw UserError(where + ": tdoa_s: " + std::to_string(line.tdoa_s.size()) +
                          " pair delays for array " + id + "'s " + std::to_string(mics) +
                          " mics (" + std::to_string(mics * (mics - 1) / 2) + " pairs)");
        if (!(line.direction.norm() > 0.5))
          throw UserError(where + ": direction: not a unit vector");
        line.direction.normalize();
        out.push_back(std::move(line));
      });
  return out;
}

std::vector<calib::ArrayNominal> nominal_arrays(const config::SiteConfig& site,
                                                std::optional<double> mic_position_std_m) {
  std::vector<calib::ArrayNominal> out;
  for (std::size_t a = 0; a < site.arrays.size(); ++a) {
    const auto& array = site.arrays[a];
    calib::ArrayNominal nominal;
    nominal.ground_height_m = site.doa_params(a).ground_height_m;
    nominal.id = array.geometry.id;
    nominal.position_m = array.geometry.position_m;
    nominal.yaw_deg = array.geometry.yaw_deg;
    nominal.pitch_deg = array.geometry.pitch_deg;
    nominal.roll_deg = array.geometry.roll_deg;
    nominal.mics_m = array.geometry.mics_m;
    nominal.mic_position_std_m = mic_position_std_m.value_or(array.geometry.mic_position_std_m);
    nominal.channel_delay_s = array.geometry.channel_delay_s;
    nominal.clock_offset_s = array.geometry.clock_offset_s;
    out.push_back(std::move(nominal));
  }
  return out;
}

std::vector<calib::TdoaFrame> frames_towards_reference(
    const std::vector<TdoaLine>& lines, const std::vector<calib::ArrayNominal>& arrays,
    const calib::ReferenceTrack& reference, double speed_of_sound_mps, double gate_deg,
    int& dropped) {
  std::vector<Eigen::Vector3d> centres;
  for (const auto& array : arrays) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& mic : array.mics_m) {
      double site[3];
      calib::rotate_array_to_site(array.yaw_deg * kRadPerDeg, array.pitch_deg * kRadPerDeg,
                                  array.roll_deg * kRadPerDeg, mic.data(), site);
      sum += Eigen::Vector3d(site[0], site[1], site[2]);
    }
    centres.push_back(array.position_m + sum / static_cast<double>(array.mics_m.size()));
  }
  std::vector<Eigen::Vector3d> fixes;
  for (const auto& sample : reference.samples()) fixes.push_back(sample.position_m);
  const double cos_gate = std::cos(gate_deg * kRadPerDeg);
  std::vector<calib::TdoaFrame> frames;
  dropped = 0;
  for (const TdoaLine& line : lines) {
    const Eigen::Vector3d& centre = centres[static_cast<std::size_t>(line.array)];
    const auto emission = reference.emission_time_s(line.time_s, centre, speed_of_sound_mps, fixes);
    // Off the track: kept, for the calibration to count (and to refuse when none is on it).
    bool towards_reference = !emission;
    if (emission) {
      const auto bracket = reference.bracket(*emission);
      const Eigen::Vector3d towards = reference.position_at(*bracket, fixes) - centre;
      towards_reference =
          towards.norm() > 0.0 && towards.normalized().dot(line.direction) >= cos_gate;
    }
    if (towards_reference) {
      frames.push_back({line.array, line.time_s, line.tdoa_s});
    } else {
      ++dropped;
    }
  }
  return frames;
}

}  // namespace dronetrack::apps
