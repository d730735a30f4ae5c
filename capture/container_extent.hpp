#pragma once
// How many frames a recording's container header declares, against how many the file holds.
//
// libsndfile quietly shortens a WAV, RF64, AIFF, W64, CAF or AU file whose header claims more
// audio than the file holds (it reports the frames present), so a recorder that died mid-write
// would look like a complete, shorter recording. This walks the container's header itself and
// compares the declared length with the bytes after the start of the audio data.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace dronetrack::capture {

struct DataExtent {
  std::string container;             // "RIFF WAV", "RIFX WAV", "RF64", "AIFF", "W64", "CAF", "AU"
  std::int64_t declared_frames = 0;  // as the header declares
  std::int64_t present_frames = 0;   // whole frames the file holds, at most declared_frames
};

// bytes_per_frame: channels x bytes per sample of a fixed-size encoding (PCM, float, A-law,
// mu-law); 0 or less for anything else (compressed), which is never checked. Nothing when the
// container is none of the above (FLAC, Ogg, ...: those are checked while reading), when it
// declares no length (a streaming placeholder: 0, 0xFFFFFFFF, CAF's -1) or when its header
// cannot be walked to the audio data.
std::optional<DataExtent> data_extent(const std::filesystem::path& file, int bytes_per_frame);

}  // namespace dronetrack::capture
