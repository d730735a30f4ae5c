#pragma once
// The calibrated site config (docs/calibration.md): the input document with every key kept and
// each array's calibrated keys replaced: position_m, yaw_deg, pitch_deg, roll_deg, mics_m,
// mic_position_std_m (the largest posterior std of its mic coordinates), channel_delay_s and
// clock_offset_s (each the input's value plus what the flight showed: the nodes that measured
// it had already applied the input's).
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "calib/site_calibration.hpp"
#include "config/site_config.hpp"

namespace dronetrack::apps {

// `site_dir` / `out_dir`: the folders of the input and output configs; relative recording paths
// are rewritten to stay pointing at the same files.
nlohmann::ordered_json calibrated_site_document(const nlohmann::ordered_json& original,
                                                const config::SiteConfig& site,
                                                const calib::CalibrationResult& result,
                                                const std::filesystem::path& site_dir,
                                                const std::filesystem::path& out_dir);

// The table `calibrate` prints: per array its frames and residuals before and after, then every
// estimate with its std, prior std and whether the flight excited it.
std::string calibration_table(const calib::CalibrationResult& result);

}  // namespace dronetrack::apps
