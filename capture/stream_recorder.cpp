#include "capture/stream_recorder.hpp"

#include <algorithm>
#include <limits>
#include <vector>

namespace dronetrack::capture {

StreamRecording record_stream(AudioSource& source, const doa::AudioBlockView& first,
                              AudioFileWriter& writer, std::int64_t max_frames,
                              const std::atomic<bool>* stop) {
  StreamRecording recording;
  const std::int64_t origin = first.first_sample;
  const std::size_t zero_frames = std::max<std::size_t>(first.frames, 1);
  const std::vector<float> zeros(zero_frames * static_cast<std::size_t>(first.channels), 0.0f);
  const auto room = [&] {
    return max_frames > 0 ? max_frames - recording.frames
                          : std::numeric_limits<std::int64_t>::max();
  };
  doa::AudioBlockView block = first;
  do {
    // Frames the source skipped (an overrun): zeros, so sample k of the file is sample k of the
    // stream.
    while (block.first_sample - origin > recording.frames && room() > 0) {
      const auto frames =
          static_cast<std::size_t>(std::min({block.first_sample - origin - recording.frames, room(),
                                             static_cast<std::int64_t>(zero_frames)}));
      writer.write(zeros.data(), frames);
      recording.frames += static_cast<std::int64_t>(frames);
      recording.gap_frames += static_cast<std::int64_t>(frames);
    }
    const auto frames =
        static_cast<std::size_t>(std::min(static_cast<std::int64_t>(block.frames), room()));
    writer.write(block.interleaved, frames);
    recording.frames += static_cast<std::int64_t>(frames);
    if (room() <= 0 || (stop && stop->load())) break;
  } while (source.next(block));
  return recording;
}

}  // namespace dronetrack::capture
