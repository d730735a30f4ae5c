#pragma once
// The per-block step every source shares: pick the array's mics out of the captured channels,
// replace NaN/Inf by 0 (one bad sample would poison a whole FFT downstream) and update the
// clipping, non-finite and level counters. Allocates nothing.
#include <cstddef>
#include <vector>

#include "capture/audio_source.hpp"

namespace dronetrack::capture {

constexpr float kClipLevel = 0.999F;        // |x| at or above this counts as clipped
constexpr double kLevelFloorDbfs = -120.0;  // reported for silence

// in: frames x in_channels interleaved; out: frames x channel_map.size() interleaved, where
// out mic i = in channel channel_map[i] (all indices must be < in_channels).
// Sets counters.peak_level_dbfs/rms_level_dbfs to this block's levels.
void map_channels_and_count(const float* in, std::size_t frames, std::size_t in_channels,
                            const std::vector<int>& channel_map, float* out,
                            SourceCounters& counters);

}  // namespace dronetrack::capture
