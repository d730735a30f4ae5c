#include "apps/recording_alignment.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "capture/recording_info.hpp"
#include "capture/recording_time.hpp"
#include "common/log.hpp"
#include "config/config_reader.hpp"

namespace dronetrack::apps {
namespace {

bool identity_map(const std::vector<int>& channel_map) {
  for (std::size_t mic = 0; mic < channel_map.size(); ++mic)
    if (channel_map[mic] != static_cast<int>(mic)) return false;
  return true;
}

std::string seconds_text(double seconds) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6f", seconds);
  return text;
}

}  // namespace

RecordingAlignment align_recordings(const config::SiteConfig& site) {
  RecordingAlignment alignment;
  alignment.start_samples.assign(site.arrays.size(), 0);
  std::vector<std::optional<capture::RecordingTime>> times;
  std::vector<double> rates_hz;
  std::size_t timed = 0;
  for (const config::ArrayConfig& array : site.arrays) {
    times.push_back(capture::read_recording_time(array.recording));
    const capture::RecordingInfo info = capture::probe_recording(array.recording);
    rates_hz.push_back(info.sample_rate_hz);
    if (!times.back()) continue;
    ++timed;
    const capture::RecordingTime& time = *times.back();
    const std::string sidecar = capture::time_sidecar_path(array.recording).string();
    if (std::fabs(time.sample_rate_hz - info.sample_rate_hz) > 1e-6 * info.sample_rate_hz)
      throw std::runtime_error(sidecar + ": sample_rate_hz " +
                               config::format_number(time.sample_rate_hz) + " but " +
                               array.recording.string() + " is at " +
                               config::format_number(info.sample_rate_hz) + " Hz");
    if (time.channels != info.channels)
      throw std::runtime_error(sidecar + ": channels " + std::to_string(time.channels) + " but " +
                               array.recording.string() + " has " + std::to_string(info.channels));
    if (time.channel_order == "mic" && !identity_map(array.channel_map))
      throw std::runtime_error(
          sidecar + ": the clip is in mic order (channel_map applied when it was cut), but the " +
          "site gives array " + array.geometry.id + " a channel_map; remove it for this replay");
    if (time.array_id != array.geometry.id)
      log::warn("replay: ", sidecar, " was recorded as array ", time.array_id,
                "; the site replays it as ", array.geometry.id);
  }
  if (timed < site.arrays.size()) {
    if (timed > 0)
      log::warn("replay: only ", timed, " of ", site.arrays.size(),
                " recordings carry a start time (FILE.json): all are taken to start together");
    alignment.utc_start_unix_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                      std::chrono::system_clock::now().time_since_epoch())
                                      .count();
    return alignment;
  }
  alignment.from_recordings = true;
  std::int64_t earliest_ns = times[0]->utc_start_unix_ns;
  std::int64_t latest_ns = earliest_ns;
  for (const auto& time : times) {
    earliest_ns = std::min(earliest_ns, time->utc_start_unix_ns);
    latest_ns = std::max(latest_ns, time->utc_start_unix_ns);
  }
  alignment.utc_start_unix_ns = earliest_ns;
  alignment.spread_s = static_cast<double>(latest_ns - earliest_ns) * 1e-9;
  std::string line = "replay: recordings started " + seconds_text(alignment.spread_s) +
                     " s apart (t = 0 is " + capture::format_utc(earliest_ns) + ")";
  for (std::size_t i = 0; i < times.size(); ++i) {
    const double offset_s = static_cast<double>(times[i]->utc_start_unix_ns - earliest_ns) * 1e-9;
    alignment.start_samples[i] = std::llround(offset_s * rates_hz[i]);
    line.append(i == 0 ? ": " : ", ").append(site.arrays[i].geometry.id).append(" at +");
    line.append(seconds_text(offset_s)).append(" s");
  }
  log::info(line);
  return alignment;
}

}  // namespace dronetrack::apps
