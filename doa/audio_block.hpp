#pragma once
// A non-owning view of a block of interleaved float samples, as capture sources deliver them.
// Channel i is mic i of the array (any channel_map is applied by the source).
#include <cstddef>
#include <cstdint>

namespace dronetrack::doa {

struct AudioBlockView {
  std::int64_t first_sample = 0;  // index of the block's first sample since stream start (t = 0)
  int channels = 0;
  std::size_t frames = 0;  // samples per channel
  const float* interleaved = nullptr;
  float sample(std::size_t frame, int channel) const {
    return interleaved[frame * static_cast<std::size_t>(channels) +
                       static_cast<std::size_t>(channel)];
  }
};

// One run of consecutive frames of a block the framer has just copied (Framer::push), with each
// channel's statistics of its samples as they came (before any non-finite one is replaced): what an
// observer of every sample (ChannelHealth) needs, from the framer's own pass over them.
struct ChannelRun {
  const float* interleaved = nullptr;  // the run's frames in the block
  std::size_t frames = 0;
  int channels = 0;
  std::int64_t first_sample = 0;
  const double* sums = nullptr;  // per channel
  const double* squares = nullptr;
  const double* peaks = nullptr;  // largest |x| (a NaN sample: its squares are NaN)
};

}  // namespace dronetrack::doa
