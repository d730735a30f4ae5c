#pragma once
// Writes multichannel float audio to a WAV file (float32) with its time metadata: the sidecar
// of recording_time.hpp and the BWF `bext` time reference. Used by `record` and by the incident
// clips. The file is an OutputFile: it appears under its name only at commit(), whole.
#include <cstddef>
#include <filesystem>
#include <memory>

#include "capture/recording_time.hpp"
#include "common/output_file.hpp"

struct sf_private_tag;

namespace dronetrack::capture {

class AudioFileWriter {
 public:
  // Throws OutputError naming the file.
  AudioFileWriter(const std::filesystem::path& file, const RecordingTime& time);
  ~AudioFileWriter();
  AudioFileWriter(const AudioFileWriter&) = delete;
  AudioFileWriter& operator=(const AudioFileWriter&) = delete;

  // `frames` interleaved frames of time.channels samples. Throws OutputError (a full disk).
  void write(const float* interleaved, std::size_t frames);
  // Closes the audio, puts it in place, then writes the sidecar. Throws OutputError.
  void commit();
  std::int64_t frames_written() const { return frames_written_; }

 private:
  std::filesystem::path file_;
  RecordingTime time_;
  std::unique_ptr<OutputFile> out_;
  sf_private_tag* handle_ = nullptr;
  std::int64_t frames_written_ = 0;
};

}  // namespace dronetrack::capture
