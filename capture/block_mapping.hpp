#pragma once
// The per-block step every source shares: pick the array's mics out of the captured channels
// and measure the block's level. Samples pass unchanged, NaN/Inf and over-range values
// included: the node counts them per channel and replaces the non-finite ones by 0 before its
// FFTs (doa/channel_health.hpp, doa/spectral_frame.hpp). Allocates nothing.
#include <cstddef>
#include <vector>

#include "capture/audio_source.hpp"

namespace dronetrack::capture {

constexpr double kLevelFloorDbfs = -120.0;  // reported for silence

// True when channel_map takes every one of in_channels in order: a block is delivered as read.
bool is_identity_map(const std::vector<int>& channel_map, std::size_t in_channels);

// Sets counters.peak_level_dbfs/rms_level_dbfs to the levels of `count` samples (of the finite
// ones; the floor when there are none).
void measure_levels(const float* samples, std::size_t count, SourceCounters& counters);

// in: frames x in_channels interleaved; out: frames x channel_map.size() interleaved, where
// out mic i = in channel channel_map[i] (all indices must be < in_channels).
void map_channels(const float* in, std::size_t frames, std::size_t in_channels,
                  const std::vector<int>& channel_map, float* out);

// map_channels, then measure_levels of the mapped block into counters (a live device's block).
void map_channels_and_count(const float* in, std::size_t frames, std::size_t in_channels,
                            const std::vector<int>& channel_map, float* out,
                            SourceCounters& counters);

}  // namespace dronetrack::capture
