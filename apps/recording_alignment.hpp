#pragma once
// Where each array's recording starts on a replay's common timeline (issue 19). Recordings that
// all carry their wall-clock start (the time sidecar of capture/recording_time.hpp: `record`,
// incident clips) are lined up by it: t = 0 is the earliest start and a later recording's first
// sample is placed at its offset, rounded to the nearest sample. Without it on every recording
// they are taken to start together (SPEC 2: t = 0 is sample 0 of every recording).
#include <cstdint>
#include <string>
#include <vector>

#include "config/site_config.hpp"

namespace dronetrack::apps {

struct RecordingAlignment {
  std::vector<std::int64_t> start_samples;  // per array, site order: stream index of sample 0
  std::int64_t utc_start_unix_ns = 0;       // wall-clock time of t = 0
  // True when every recording carried its start; false: utc_start_unix_ns is the time the
  // replay started (a common origin for clips cut from it, not the recordings' time).
  bool from_recordings = false;
  double spread_s = 0.0;  // latest start minus earliest
};

// Reads the sidecars and logs one line saying how far apart the recordings started (or, when
// only some carry a start, that they are taken to start together). Throws std::runtime_error
// with one line for a sidecar that is invalid or contradicts its recording (rate, channels, a
// mic-order clip under a channel_map).
RecordingAlignment align_recordings(const config::SiteConfig& site);

}  // namespace dronetrack::apps
