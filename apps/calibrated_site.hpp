#pragma once
// The calibrated site config (docs/calibration.md): the input document with every key kept and
// each array's calibrated keys replaced: position_m, yaw_deg, mics_m, mic_position_std_m, and
// the new channel_delay_s and clock_offset_s (added to any the input had: the nodes that
// measured the flight had already applied those). A pitch or roll found is folded into mics_m
// (the array frame turned by pitch and roll), which the site config can carry today.
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "calib/site_calibration.hpp"
#include "config/site_config.hpp"

namespace dronetrack::apps {

// `site_dir` / `out_dir`: the folders of the input and output configs; relative recording paths
// are rewritten to stay pointing at the same files.
nlohmann::json calibrated_site_document(const nlohmann::json& original,
                                        const config::SiteConfig& site,
                                        const calib::CalibrationResult& result,
                                        const std::filesystem::path& site_dir,
                                        const std::filesystem::path& out_dir);

// The table `calibrate` prints: per array its frames and residuals before and after, then every
// estimate with its std, prior std and whether the flight excited it.
std::string calibration_table(const calib::CalibrationResult& result);

}  // namespace dronetrack::apps
