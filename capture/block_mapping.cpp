#include "capture/block_mapping.hpp"

#include <algorithm>
#include <cmath>

namespace dronetrack::capture {
namespace {
double to_dbfs(double amplitude) {
  return amplitude > 0.0 ? std::max(kLevelFloorDbfs, 20.0 * std::log10(amplitude))
                         : kLevelFloorDbfs;
}
}  // namespace

void map_channels_and_count(const float* in, std::size_t frames, std::size_t in_channels,
                            const std::vector<int>& channel_map, float* out,
                            SourceCounters& counters) {
  const std::size_t mics = channel_map.size();
  double peak = 0.0;
  double sum_squares = 0.0;
  std::size_t finite = 0;
  for (std::size_t frame = 0; frame < frames; ++frame) {
    const float* in_frame = in + frame * in_channels;
    float* out_frame = out + frame * mics;
    for (std::size_t mic = 0; mic < mics; ++mic) {
      const float sample = in_frame[static_cast<std::size_t>(channel_map[mic])];
      out_frame[mic] = sample;
      if (!std::isfinite(sample)) continue;
      ++finite;
      peak = std::max(peak, static_cast<double>(std::fabs(sample)));
      sum_squares += static_cast<double>(sample) * static_cast<double>(sample);
    }
  }
  counters.peak_level_dbfs = to_dbfs(peak);
  counters.rms_level_dbfs =
      finite > 0 ? to_dbfs(std::sqrt(sum_squares / static_cast<double>(finite))) : kLevelFloorDbfs;
}

}  // namespace dronetrack::capture
