#pragma once
// The picture the HTTP API serves: site layout, current tracks and their history, node health
// with each array's latest DOA, and alerts. Thread-safe: the fusion/replay thread publishes,
// the server's threads read snapshots. Publishing never blocks on a client.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"
#include "doa/node_status.hpp"
#include "fusion/fusion_params.hpp"
#include "fusion/track_report.hpp"
#include "fusion/zone_monitor.hpp"

namespace dronetrack::http_api {

struct SiteLayout {
  std::vector<doa::ArrayGeometry> arrays;
  std::vector<fusion::Zone> zones;
  double speed_of_sound_mps = 343.0;
};

class LiveState;  // defined in live_state.cpp by the http_api owner

}  // namespace dronetrack::http_api
