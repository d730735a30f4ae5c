#include "sim/impulsive_noise.hpp"

#include <algorithm>
#include <cmath>

#include "sim/alpha_stable.hpp"
#include "sim/random.hpp"

namespace dronetrack::sim {
namespace {
// Stream kinds beside noise.cpp's 10-14.
enum ImpulsiveStream : std::uint64_t { kBurstSlots = 15, kBurstSamples = 16 };
}  // namespace

ImpulsiveCounts add_impulsive_noise(const ImpulsiveNoise& spec, double rms, double sample_rate_hz,
                                    std::uint64_t seed, std::size_t array_index,
                                    std::size_t channels, std::size_t frames, float* interleaved) {
  ImpulsiveCounts counts;
  if (!spec.enabled || channels == 0 || frames == 0) return counts;
  const auto slot_frames = std::max<std::size_t>(
      1, static_cast<std::size_t>(std::lround(spec.burst_s * sample_rate_hz)));
  counts.slots = (frames + slot_frames - 1) / slot_frames;
  const AlphaStable law{spec.alpha, 0.0, rms / std::sqrt(2.0), 0.0};
  // Shared slots: one stream for the array; per channel: one per channel.
  Random shared_slots(seed, stream_id(kBurstSlots, array_index));
  for (std::size_t channel = 0; channel < channels; ++channel) {
    Random own_slots(seed, stream_id(kBurstSlots, array_index, channel + 1));
    Random samples(seed, stream_id(kBurstSamples, array_index, channel));
    Random shared = shared_slots;  // every channel replays the array's slot draws
    for (std::size_t slot = 0; slot < counts.slots; ++slot) {
      const bool burst = (spec.per_channel ? own_slots.uniform() : shared.uniform()) < spec.share;
      if (!burst) continue;
      if (spec.per_channel || channel == 0) ++counts.bursts;
      const std::size_t end = std::min(frames, (slot + 1) * slot_frames);
      for (std::size_t n = slot * slot_frames; n < end; ++n) {
        float& sample = interleaved[n * channels + channel];
        const double value = sample + draw_alpha_stable(law, samples);
        if (std::abs(value) >= 1.0) ++counts.clipped_samples;
        sample = static_cast<float>(std::clamp(value, -1.0, 1.0));
      }
    }
  }
  return counts;
}

}  // namespace dronetrack::sim
