#pragma once
// Health of one array node, published about once a second (DDS NodeStatus, /api/nodes).
#include <cstdint>
#include <string>
#include <vector>

#include "doa/array_health.hpp"
#include "doa/channel_health.hpp"

namespace dronetrack::doa {

inline constexpr double kMaxLevelOffset_db = 300.0;  // |level_offset_db| bound (DDS validation)
inline constexpr double kMaxHealthDelay_us = 1e6;    // |delay_offset_us|, residuals' bound

// One channel (mic) of the node: its audio health (doa/channel_health.hpp) and how it compares
// with the array's other channels (doa/array_health.hpp).
struct ChannelStatus {
  HealthFlags problems = 0;       // present on the last ~1 s judged (bit i: HealthProblem i)
  HealthFlags problems_seen = 0;  // present at any time since the node started
  std::int64_t non_finite_samples = 0;
  std::int64_t clipped_samples = 0;
  double rms_dbfs = -120.0;            // of the last ~1 s judged (floor -120)
  ArrayFlags array_problems = 0;       // on each check's last judgement (bit i: ArrayProblem i)
  ArrayFlags array_problems_seen = 0;  // at any time since the node started
  double level_offset_db = 0.0;        // in-band level minus the array's median, after gains
  double delay_offset_us = 0.0;        // fitted channel delay minus the median channel's
  // That offset's cluster-robust std (doa/channel_delay_fit.hpp); kMaxHealthDelay_us until the
  // delay is judged (too few direction sectors seen, or an array without a delay fit).
  double delay_std_us = kMaxHealthDelay_us;
};

inline constexpr std::size_t kMaxStatusChannels = 8;  // the pipeline's mic limit; DDS array size

struct NodeStatus {
  std::string array_id;
  double time_s = 0.0;  // recording/stream time of the report
  bool alive = true;    // false: the node said goodbye or the fusion lost its liveliness
  double sample_rate_hz = 0.0;
  std::int64_t overruns = 0;
  // Capture gaps since the node started: jumps of the sample index (lost blocks) and stretches
  // of digital silence on every channel (what many drivers deliver for a lost buffer).
  std::int64_t dropouts = 0;
  std::int64_t clipped_samples = 0;     // all channels, |x| >= 0.999
  std::int64_t non_finite_samples = 0;  // all channels, NaN/inf (replaced by 0)
  double level_dbfs = -120.0;
  double noise_floor_dbfs = -120.0;
  double snr_db = 0.0;
  bool detecting = false;
  double closure_residual_us = 0.0;  // largest |running median| of a triple's delay closure
  double fit_residual_us = 0.0;      // running median RMS misfit of the pair delays to a plane wave
  std::string software_version;
  // Incident capture (docs/deployment.md "Incident recordings"): clips saved, and writes that
  // failed (the audio ring or a clip: a full disk, an I/O error; processing went on).
  std::int64_t incident_clips = 0;
  std::int64_t incident_write_errors = 0;
  std::vector<ChannelStatus> channels;  // index: mic (0-based); at most kMaxStatusChannels
};

}  // namespace dronetrack::doa
