#pragma once
// What `dronetrack calibrate` reads, turned into calib/'s plain structs: the reference log (a
// GPS logger's or a surveyed loudspeaker's positions), the pair delays (`replay --tdoa-out`
// lines, or the nodes run over the recordings), the site's arrays as nominal values. Every
// problem is one UserError line naming FILE:LINE and what is wrong.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/reference_track.hpp"
#include "calib/site_calibration.hpp"
#include "config/site_config.hpp"
#include "doa/doa_measurement.hpp"

namespace dronetrack::apps {

// `{"t": s, "position_m": [x, y, z]}` per line, times increasing, optionally
// `"position_std_m": s` (the logger's stated accuracy).
struct ReferenceLog {
  std::vector<calib::ReferenceSample> samples;
  std::optional<double> position_std_m;  // the largest stated on any line
};
ReferenceLog read_reference_log(const std::filesystem::path& file);

// One frame of one array: `{"t":..,"array":"A1","source":0,"direction":[..],"tdoa_s":[..]}`,
// the line `replay --tdoa-out` writes (apps/jsonl_output.hpp).
struct TdoaLine {
  int array = 0;  // index into the site's arrays
  double time_s = 0.0;
  int source = 0;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // the node's, site frame
  std::vector<double> tdoa_s;                            // mic pairs i < j, lexicographic
};
TdoaLine tdoa_line_of(const doa::DoaMeasurement& doa);
std::vector<TdoaLine> read_tdoa_lines(const std::filesystem::path& file,
                                      const config::SiteConfig& site);

// The site's arrays as the calibration's nominal values. `mic_position_std_m` (when set)
// replaces every array's own.
std::vector<calib::ArrayNominal> nominal_arrays(const config::SiteConfig& site,
                                                std::optional<double> mic_position_std_m);

// The lines that heard the reference: the node's direction within `gate_deg` of the direction
// from the array to where the reference was when the sound left it. Others (another source, a
// reflection) are counted in `dropped`; lines off the reference's time span are kept (the
// calibration counts them, and refuses when no line is on it).
std::vector<calib::TdoaFrame> frames_towards_reference(
    const std::vector<TdoaLine>& lines, const std::vector<calib::ArrayNominal>& arrays,
    const calib::ReferenceTrack& reference, double speed_of_sound_mps, double gate_deg,
    int& dropped);

}  // namespace dronetrack::apps
