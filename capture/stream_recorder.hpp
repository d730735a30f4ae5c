#pragma once
// The loop of `dronetrack record`: an audio source's blocks into an AudioFileWriter, keeping the
// file's sample index equal to the source's sample clock (a live overrun's lost frames are
// written as zeros and counted), so the time sidecar stays true for every sample.
#include <atomic>
#include <cstdint>

#include "capture/audio_file_writer.hpp"
#include "capture/audio_source.hpp"

namespace dronetrack::capture {

struct StreamRecording {
  std::int64_t frames = 0;      // written, gaps included
  std::int64_t gap_frames = 0;  // zeros written for frames the source lost
};

// Writes `first` (already read: the caller stamped the file's start from it) and the blocks
// after it until the source ends, `max_frames` are written (0: no limit) or `*stop` is set.
// Allocates one block of zeros for the gaps, nothing per block. Throws OutputError (a full disk)
// and whatever the source throws.
StreamRecording record_stream(AudioSource& source, const doa::AudioBlockView& first,
                              AudioFileWriter& writer, std::int64_t max_frames,
                              const std::atomic<bool>* stop);

}  // namespace dronetrack::capture
