#pragma once
// Impulsive noise in the audio (issue 17, seed 001): bursts of alpha-stable samples, the kind a
// wind gust on a windscreen, a clatter or a crackle puts on a microphone. Time is cut into slots of
// burst_s; a slot carries a burst with probability `share`, for the whole array at once (one
// event heard by every mic) or for each channel on its own (`per_channel`: local to one
// windscreen). Inside a burst every sample gets an independent draw of S(alpha, 0, c, 0)
// (sim/alpha_stable.hpp) with c = rms / sqrt(2), so at alpha = 2 a burst is white Gaussian noise of
// that RMS; below 2 its samples have no variance and a few are very large. A sample is clipped to
// full scale (an ADC's range). Key noise.impulsive (docs/scenarios.md).
#include <cstddef>
#include <cstdint>
#include <optional>

namespace dronetrack::sim {

struct ImpulsiveNoise {
  bool enabled = false;
  // Scale as for the other noises: in-band SNR against the drones (the RMS of a Gaussian burst of
  // the same c), or absolute RMS in dB SPL.
  std::optional<double> snr_db;
  std::optional<double> level_db_spl;
  double share = 0.1;     // of the slots carrying a burst, [0, 1]
  double burst_s = 0.02;  // slot (burst) length, s
  double alpha = 1.5;     // stability, (0, 2]
  bool per_channel = false;
};

// What was rendered: slots with a burst (per channel counted once per channel when per_channel),
// and samples that hit full scale.
struct ImpulsiveCounts {
  std::size_t bursts = 0;
  std::size_t slots = 0;
  std::size_t clipped_samples = 0;
};

// Adds bursts of scale rms (see above) to the channels of an interleaved buffer. Streams come from
// (seed, array_index[, channel]): reproducible, independent between arrays.
ImpulsiveCounts add_impulsive_noise(const ImpulsiveNoise& spec, double rms, double sample_rate_hz,
                                    std::uint64_t seed, std::size_t array_index,
                                    std::size_t channels, std::size_t frames, float* interleaved);

}  // namespace dronetrack::sim
