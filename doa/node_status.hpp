#pragma once
// Health of one array node, published about once a second (DDS NodeStatus, /api/nodes).
#include <cstdint>
#include <string>
#include <vector>

#include "doa/channel_health.hpp"

namespace dronetrack::doa {

// One channel (mic) of the node: its audio health (doa/channel_health.hpp).
struct ChannelStatus {
  HealthFlags problems = 0;       // present on the last ~1 s judged (bit i: HealthProblem i)
  HealthFlags problems_seen = 0;  // present at any time since the node started
  std::int64_t non_finite_samples = 0;
  std::int64_t clipped_samples = 0;
  double rms_dbfs = -120.0;  // of the last ~1 s judged (floor -120)
};

inline constexpr std::size_t kMaxStatusChannels = 8;  // the pipeline's mic limit; DDS array size

struct NodeStatus {
  std::string array_id;
  double time_s = 0.0;  // recording/stream time of the report
  bool alive = true;    // false: the node said goodbye or the fusion lost its liveliness
  double sample_rate_hz = 0.0;
  std::int64_t overruns = 0;
  std::int64_t clipped_samples = 0;     // all channels, |x| >= 0.999
  std::int64_t non_finite_samples = 0;  // all channels, NaN/inf (replaced by 0)
  double level_dbfs = -120.0;
  double noise_floor_dbfs = -120.0;
  double snr_db = 0.0;
  bool detecting = false;
  std::string software_version;
  std::vector<ChannelStatus> channels;  // index: mic (0-based); at most kMaxStatusChannels
};

}  // namespace dronetrack::doa
