#include "config/pose_file.hpp"

#include <cmath>
#include <fstream>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/config_reader.hpp"
#include "doa/array_geometry.hpp"

namespace dronetrack::config {

namespace {

// One line's keys, each checked; the first problem is thrown with `where`.
doa::PoseSample parse_pose_line(const nlohmann::json& node, const std::string& where,
                                const PoseFileLimits& limits) {
  Diagnostics diagnostics;
  doa::PoseSample sample;
  {
    ObjectReader reader(node, "", diagnostics);
    // Recording time: ~300 years either side of 0 holds a Unix time in seconds too.
    sample.time_s = reader.required_number("t", -1e10, 1e10).value_or(0.0);
    if (auto position = reader.vector3("position_m", true)) {
      sample.position_m = *position;
      if (position->cwiseAbs().maxCoeff() > limits.max_coordinate_m)
        diagnostics.error("position_m",
                          "a coordinate beyond " + format_number(limits.max_coordinate_m / 1e3) +
                              " km of the site origin (acoustic range is a few km; metres?)");
    }
    sample.yaw_deg = reader.required_number("yaw_deg", -360.0, 360.0).value_or(0.0);
    sample.pitch_deg = reader.number("pitch_deg", 0.0, -90.0, 90.0);
    sample.roll_deg = reader.number("roll_deg", 0.0, -180.0, 180.0);
    // Other keys (velocity, fix quality, ...) are the adapter's business: not warned about.
    for (const auto& item : node.items()) reader.accept(item.key());
  }
  if (!diagnostics.errors.empty()) throw std::runtime_error(where + ": " + diagnostics.errors[0]);
  return sample;
}

}  // namespace

doa::PoseTrack read_pose_file(const std::filesystem::path& file, const PoseFileLimits& limits) {
  const std::string name = file.string();
  std::error_code error;
  if (std::filesystem::is_directory(file, error))
    throw std::runtime_error(name + ": is a directory, not a pose file");
  std::ifstream stream(file, std::ios::binary);
  if (!stream) throw std::runtime_error(name + ": cannot open pose file");
  const auto size = std::filesystem::file_size(file, error);
  if (!error && size > kMaxPoseFileBytes)
    throw std::runtime_error(name + ": " + std::to_string(size) + " bytes; a pose file may be " +
                             "at most " + std::to_string(kMaxPoseFileBytes >> 20) + " MiB");
  std::vector<doa::PoseSample> samples;
  LineReader lines(stream, kMaxLineBytes);
  std::string line;
  std::size_t bytes = 0;
  int previous_line = 0;
  while (lines.next(line)) {
    // A FIFO has no size to check up front.
    bytes += line.size() + 1;
    if (bytes > kMaxPoseFileBytes)
      throw std::runtime_error(name + ": larger than " + std::to_string(kMaxPoseFileBytes >> 20) +
                               " MiB; a pose file may be at most that");
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::string where = name + ":" + std::to_string(lines.number());
    nlohmann::json node;
    try {
      node = nlohmann::json::parse(line);
    } catch (const nlohmann::json::exception&) {
      const bool non_finite =
          line.find("NaN") != std::string::npos || line.find("Infinity") != std::string::npos;
      throw std::runtime_error(where + ": invalid JSON" +
                               (non_finite ? " (NaN and Infinity are not JSON numbers)" : "") +
                               "; expected {\"t\": s, \"position_m\": [x, y, z], \"yaw_deg\": d}");
    }
    const doa::PoseSample sample = parse_pose_line(node, where, limits);
    if (!samples.empty()) {
      const doa::PoseSample& before = samples.back();
      const std::string since = " after line " + std::to_string(previous_line);
      if (!(sample.time_s > before.time_s))
        throw std::runtime_error(where + ": t " + format_number(sample.time_s) + " s is not" +
                                 since + "'s " + format_number(before.time_s) +
                                 " s (times must increase)");
      if (sample.time_s - before.time_s > limits.max_gap_s)
        throw std::runtime_error(
            where + ": t jumps " + format_number(sample.time_s - before.time_s) + " s" + since +
            ", more than " + limits.max_gap_key + " " + format_number(limits.max_gap_s) +
            " s: the pose in between is unknown");
      const double turn_deg = doa::wrap_deg_180(sample.yaw_deg - before.yaw_deg);
      if (std::abs(turn_deg) > doa::kMaxPoseYawStep_deg)
        throw std::runtime_error(
            where + ": yaw turns " + format_number(turn_deg) + " deg" + since + ", more than " +
            format_number(doa::kMaxPoseYawStep_deg) +
            " deg between lines: the pose rate is too low for the platform's turn");
    }
    samples.push_back(sample);
    previous_line = lines.number();
  }
  if (lines.too_long())
    throw std::runtime_error(name + ":" + std::to_string(lines.number()) + ": line longer than " +
                             std::to_string(kMaxLineBytes) +
                             " bytes (a pose line is under 200 bytes)");
  if (stream.bad()) throw std::runtime_error(name + ": read error");
  if (samples.size() < 2)
    throw std::runtime_error(name + ": " + std::to_string(samples.size()) +
                             " pose lines; a pose file needs at least 2 (it is interpolated)");
  return doa::PoseTrack(std::move(samples));
}

}  // namespace dronetrack::config
