#pragma once
// What a recording file holds, read from its header without decoding it.
#include <cstdint>
#include <filesystem>
#include <string>

namespace dronetrack::capture {

struct RecordingInfo {
  int channels = 0;
  double sample_rate_hz = 0.0;
  std::int64_t frames = 0;  // samples per channel
  std::string format;       // e.g. "WAV float32", "FLAC PCM24"
};

// Throws std::runtime_error "<file>: <what is wrong>" for a missing or unreadable file.
RecordingInfo probe_recording(const std::filesystem::path& file);

}  // namespace dronetrack::capture
