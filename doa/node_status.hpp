#pragma once
// Health of one array node, published about once a second (DDS NodeStatus, /api/nodes).
#include <cstdint>
#include <string>

namespace dronetrack::doa {

struct NodeStatus {
  std::string array_id;
  double time_s = 0.0;  // recording/stream time of the report
  bool alive = true;    // false: the node said goodbye or the fusion lost its liveliness
  double sample_rate_hz = 0.0;
  std::int64_t overruns = 0;
  std::int64_t clipped_samples = 0;
  std::int64_t non_finite_samples = 0;
  double level_dbfs = -120.0;
  double noise_floor_dbfs = -120.0;
  double snr_db = 0.0;
  bool detecting = false;
  std::string software_version;
};

}  // namespace dronetrack::doa
