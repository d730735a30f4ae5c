#pragma once
// A whole replay as `replay` and `demo` run it: outputs opened, optionally served over HTTP,
// nodes and fusion run, summary logged, then (when serving) kept up until Ctrl-C.
#include <limits>
#include <string>

#include "config/site_config.hpp"
#include "sim/doa_outliers.hpp"

namespace dronetrack::apps {

struct ReplaySessionOptions {
  std::string tracks_out;  // "" with doa_out also "": tracks to stdout
  std::string doa_out;
  std::string tdoa_out;    // full-rank DOAs' pair delays as JSON lines, for calibrate; "" for none
  std::string alerts_out;  // zone alerts and class changes as JSON lines; "" for none
  std::string plot_out;    // HTML page of the tracks and DOAs (docs/plots.md); "" for none
  std::string doa_in;      // DOA lines to run the fusion alone on, instead of the recordings
  // With doa_in: the end of the audio the DOAs were made from (seconds, the DOAs' clock). The
  // tracks are reported up to it, as a replay of that audio does; NaN: up to the last DOA.
  double doa_in_audio_end_s = std::numeric_limits<double>::quiet_NaN();
  sim::DoaOutlierSettings
      doa_outliers;  // impulsive errors added to the doa_in lines (share 0: none)
  std::string http;  // ADDR:PORT to serve on; "" for none
  bool realtime = false;
  double max_duration_s = 0.0;
  bool keep_serving = true;  // after the recordings end, serve until Ctrl-C
};

int run_replay_session(const config::SiteConfig& site, const ReplaySessionOptions& options);

}  // namespace dronetrack::apps
