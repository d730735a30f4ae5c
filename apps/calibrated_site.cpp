#include "apps/calibrated_site.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "doa/array_geometry.hpp"

namespace dronetrack::apps {
namespace {

// The double nearest to `value` written with `decimals` decimals, so the file reads as a person
// would write it (0.47114, not 0.47114000000000006: JSON numbers print in their shortest form).
double rounded(double value, int decimals) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  return std::strtod(text, nullptr);
}

nlohmann::ordered_json vector_json(const Eigen::Vector3d& v, int decimals) {
  return nlohmann::ordered_json::array(
      {rounded(v.x(), decimals), rounded(v.y(), decimals), rounded(v.z(), decimals)});
}

std::filesystem::path relocated(const std::filesystem::path& path,
                                const std::filesystem::path& site_dir,
                                const std::filesystem::path& out_dir) {
  if (path.is_absolute()) return path;
  const std::filesystem::path absolute = std::filesystem::absolute(site_dir / path);
  return std::filesystem::relative(absolute, std::filesystem::absolute(out_dir));
}

std::string flag(const calib::Estimate& estimate) {
  if (estimate.prior_std <= 0.0) return estimate.std > 0.0 ? "from levels" : "fixed";
  return estimate.excited ? "" : "unexcited: kept its prior";
}

void row(std::string& out, const std::string& name, const calib::Estimate& estimate, double scale,
         const char* unit, int decimals) {
  char line[256];
  std::snprintf(line, sizeof line, "  %-22s %12.*f -> %12.*f +- %-9.*f %-4s (prior +- %.*f) %s\n",
                name.c_str(), decimals, estimate.nominal * scale, decimals, estimate.value * scale,
                decimals, estimate.std * scale, unit, decimals, estimate.prior_std * scale,
                flag(estimate).c_str());
  out += line;
}

}  // namespace

nlohmann::ordered_json calibrated_site_document(const nlohmann::ordered_json& original,
                                                const config::SiteConfig& site,
                                                const calib::CalibrationResult& result,
                                                const std::filesystem::path& site_dir,
                                                const std::filesystem::path& out_dir) {
  nlohmann::ordered_json document = original;
  for (std::size_t a = 0; a < result.arrays.size(); ++a) {
    const calib::ArrayCalibration& calibration = result.arrays[a];
    const doa::ArrayGeometry& before = site.arrays[a].geometry;
    nlohmann::ordered_json& array = document["arrays"][a];
    const calib::ArrayNominal& after = calibration.calibrated;
    array["position_m"] = vector_json(after.position_m, 4);
    array["yaw_deg"] = rounded(doa::wrap_deg_180(after.yaw_deg), 4);
    array["pitch_deg"] = rounded(after.pitch_deg, 4);
    array["roll_deg"] = rounded(doa::wrap_deg_180(after.roll_deg), 4);
    nlohmann::ordered_json mics = nlohmann::ordered_json::array();
    double mic_std_m = 0.0;
    for (std::size_t i = 0; i < after.mics_m.size(); ++i) {
      mics.push_back(vector_json(after.mics_m[i], 5));
      for (const auto& coordinate : calibration.mic_position_m[i])
        mic_std_m = std::max(mic_std_m, coordinate.std);
    }
    array["mics_m"] = mics;
    if (before.mic_position_std_m > 0.0 || mic_std_m > 0.0)
      array["mic_position_std_m"] = rounded(mic_std_m, 5);
    nlohmann::ordered_json delays = nlohmann::ordered_json::array();
    for (const calib::Estimate& delay : calibration.channel_delay_s)
      delays.push_back(rounded(delay.value, 8));
    array["channel_delay_s"] = delays;
    if (!calibration.channel_gain_db.empty()) {
      nlohmann::ordered_json gains = nlohmann::ordered_json::array();
      for (const calib::Estimate& gain : calibration.channel_gain_db)
        gains.push_back(rounded(gain.value, 3));
      array["channel_gain_db"] = gains;
    }
    array["clock_offset_s"] = rounded(calibration.clock_offset_s.value, 6);
    if (array.contains("recording") && array["recording"].is_string())
      array["recording"] =
          relocated(array["recording"].get<std::string>(), site_dir, out_dir).generic_string();
  }
  return document;
}

std::string calibration_table(const calib::CalibrationResult& result) {
  std::string out;
  char line[256];
  std::snprintf(line, sizeof line,
                "calibration: %d frames (%d off the reference, %d outliers), %d reference "
                "positions; TDOA "
                "noise std %.2f us (%s); frames' errors correlated: weighed as %.2fx fewer\n",
                result.frames_used, result.frames_off_reference, result.frames_rejected,
                result.reference_samples_used, result.tdoa_std_s * 1e6,
                result.tdoa_std_estimated ? "estimated" : "given", result.correlation_inflation);
  out += line;
  std::snprintf(line, sizeof line,
                "TDOA residuals: rms %.2f us -> %.2f us, median |r| %.2f us -> %.2f us\n",
                result.before.rms_s * 1e6, result.after.rms_s * 1e6,
                result.before.median_abs_s * 1e6, result.after.median_abs_s * 1e6);
  out += line;
  for (const calib::ArrayCalibration& array : result.arrays) {
    std::snprintf(line, sizeof line,
                  "array %s: %d frames from %d distinct directions; residual rms %.2f us -> "
                  "%.2f us\n",
                  array.id.c_str(), array.frames, array.distinct_directions,
                  array.before.rms_s * 1e6, array.after.rms_s * 1e6);
    out += line;
    row(out, "yaw_deg", array.yaw_deg, 1.0, "deg", 4);
    row(out, "pitch_deg", array.pitch_deg, 1.0, "deg", 4);
    row(out, "roll_deg", array.roll_deg, 1.0, "deg", 4);
    const char* axes[3] = {"x", "y", "z"};
    for (std::size_t k = 0; k < 3; ++k)
      row(out, std::string("position_m.") + axes[k], array.position_m[k], 1e3, "mm", 2);
    for (std::size_t i = 0; i < array.mic_position_m.size(); ++i) {
      for (std::size_t k = 0; k < 3; ++k)
        row(out, "mics_m[" + std::to_string(i) + "]." + axes[k], array.mic_position_m[i][k], 1e3,
            "mm", 2);
    }
    for (std::size_t i = 0; i < array.channel_delay_s.size(); ++i)
      row(out, "channel_delay_s[" + std::to_string(i) + "]", array.channel_delay_s[i], 1e6, "us",
          2);
    for (std::size_t i = 0; i < array.channel_gain_db.size(); ++i)
      row(out, "channel_gain_db[" + std::to_string(i) + "]", array.channel_gain_db[i], 1.0, "dB",
          3);
    row(out, "clock_offset_s", array.clock_offset_s, 1e3, "ms", 3);
    if (array.ground_echo_pull.prior_std > 0.0)  // fitted only with --ground-echo
      row(out, "ground_echo_pull", array.ground_echo_pull, 1.0, "", 3);
  }
  return out;
}

}  // namespace dronetrack::apps
