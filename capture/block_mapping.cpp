#include "capture/block_mapping.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace dronetrack::capture {
namespace {
double to_dbfs(double amplitude) {
  return amplitude > 0.0 ? std::max(kLevelFloorDbfs, 20.0 * std::log10(amplitude))
                         : kLevelFloorDbfs;
}
}  // namespace

bool is_identity_map(const std::vector<int>& channel_map, std::size_t in_channels) {
  if (channel_map.size() != in_channels) return false;
  for (std::size_t mic = 0; mic < channel_map.size(); ++mic)
    if (channel_map[mic] != static_cast<int>(mic)) return false;
  return true;
}

void measure_levels(const float* samples, std::size_t count, SourceCounters& counters) {
  // Independent partial sums per lane: one running sum is a chain of dependent additions the
  // compiler may not reorder (no -ffast-math), four cycles a sample; lanes let it vectorise.
  // Finiteness and |x| from the bits: a float compare would be a branch (-ftrapping-math), and
  // for non-negative floats the larger bit pattern is the larger number.
  constexpr std::size_t kLanes = 8;
  constexpr std::uint32_t kExponent = 0x7f800000U;  // all ones: inf or NaN
  constexpr std::uint32_t kMagnitude = 0x7fffffffU;
  std::uint32_t peak_bits[kLanes] = {};
  double sum_squares[kLanes] = {};
  std::uint32_t finite[kLanes] = {};
  const std::size_t whole = count - count % kLanes;
  for (std::size_t i = 0; i < whole; i += kLanes) {
#pragma GCC unroll 8
    for (std::size_t lane = 0; lane < kLanes; ++lane) {
      const std::uint32_t bits = std::bit_cast<std::uint32_t>(samples[i + lane]);
      const std::uint32_t is_finite = (bits & kExponent) != kExponent ? 1U : 0U;
      const std::uint32_t kept_bits = bits & kMagnitude & (0U - is_finite);  // |x| or 0
      peak_bits[lane] = std::max(peak_bits[lane], kept_bits);
      const auto kept = static_cast<double>(std::bit_cast<float>(kept_bits));
      sum_squares[lane] += kept * kept;
      finite[lane] += is_finite;
    }
  }
  double block_peak = 0.0;
  double block_sum_squares = 0.0;
  std::size_t block_finite = 0;
  for (std::size_t lane = 0; lane < kLanes; ++lane) {
    block_peak = std::max(block_peak, static_cast<double>(std::bit_cast<float>(peak_bits[lane])));
    block_sum_squares += sum_squares[lane];
    block_finite += finite[lane];
  }
  for (std::size_t i = whole; i < count; ++i) {
    const float magnitude = std::fabs(samples[i]);
    if (!(magnitude <= std::numeric_limits<float>::max())) continue;
    block_peak = std::max(block_peak, static_cast<double>(magnitude));
    block_sum_squares += static_cast<double>(magnitude) * static_cast<double>(magnitude);
    ++block_finite;
  }
  counters.peak_level_dbfs = to_dbfs(block_peak);
  counters.rms_level_dbfs =
      block_finite > 0 ? to_dbfs(std::sqrt(block_sum_squares / static_cast<double>(block_finite)))
                       : kLevelFloorDbfs;
}

void map_channels(const float* in, std::size_t frames, std::size_t in_channels,
                  const std::vector<int>& channel_map, float* out) {
  const std::size_t mics = channel_map.size();
  if (is_identity_map(channel_map, in_channels)) {
    std::copy(in, in + frames * in_channels, out);
    return;
  }
  for (std::size_t frame = 0; frame < frames; ++frame) {
    const float* in_frame = in + frame * in_channels;
    float* out_frame = out + frame * mics;
    for (std::size_t mic = 0; mic < mics; ++mic)
      out_frame[mic] = in_frame[static_cast<std::size_t>(channel_map[mic])];
  }
}

void map_channels_and_count(const float* in, std::size_t frames, std::size_t in_channels,
                            const std::vector<int>& channel_map, float* out,
                            SourceCounters& counters) {
  map_channels(in, frames, in_channels, channel_map, out);
  measure_levels(out, frames * channel_map.size(), counters);
}

}  // namespace dronetrack::capture
