#pragma once
// A moving array's pose file (issue 15, docs/contract.md "Pose file"): JSON lines
// {"t": s, "position_m": [x, y, z], "yaw_deg": d} with optional "pitch_deg", "roll_deg", t on
// the recording's clock. Read and checked once, at config load; the first problem stops the
// read with one line naming FILE:LINE.
#include <cstddef>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "doa/pose_track.hpp"

namespace dronetrack::config {

// A pose file at 100 Hz for a day is ~700 MB; a few hours of it fit.
inline constexpr std::size_t kMaxPoseFileBytes = 256u << 20;

struct PoseFileLimits {
  // Consecutive lines further apart than this leave the pose between them unknown.
  double max_gap_s = 1.0;
  // Absurd coordinates: the site config's bound (100 km).
  double max_coordinate_m = 1e5;
  // The key that set max_gap_s, named in the gap's error ("arrays[0].pose_max_gap_s").
  std::string max_gap_key = "pose_max_gap_s";
};

// Throws std::runtime_error "FILE:LINE: what" (or "FILE: what" for the file as a whole).
doa::PoseTrack read_pose_file(const std::filesystem::path& file, const PoseFileLimits& limits);

}  // namespace dronetrack::config
