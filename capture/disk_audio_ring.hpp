#pragma once
// The last N seconds of one array's raw multichannel audio, on disk: one fixed-size file of
// capacity_frames x channels float32 samples, written in turn (sample index k at slot
// k mod capacity_frames), so its size never grows and a write is one pwrite of a block. The
// incident clips are cut from it (apps/incident_recorder.hpp).
//
// Write errors (a full disk, an I/O error) are counted, never thrown: the node's processing goes
// on; the frames from before the failure are dropped from what read() offers, so a clip never
// mixes in stale samples. So is a gap in the stream (a live overrun skips sample indices).
// append() allocates nothing.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "doa/audio_block.hpp"

namespace dronetrack::capture {

class DiskAudioRing {
 public:
  // Creates (or truncates) `file` at its full size. Throws std::runtime_error "<file>: <what>".
  DiskAudioRing(const std::filesystem::path& file, int channels, std::int64_t capacity_frames);
  ~DiskAudioRing();
  DiskAudioRing(const DiskAudioRing&) = delete;
  DiskAudioRing& operator=(const DiskAudioRing&) = delete;

  void append(const doa::AudioBlockView& block);
  // Copies frames [first_sample, first_sample + frames) into `interleaved`. False (nothing
  // copied) when any of them is not held (too old, not yet written, or lost to a write error),
  // or on a read error (counted).
  bool read(std::int64_t first_sample, std::size_t frames, float* interleaved);

  // The held span: [oldest_sample(), end_sample()).
  std::int64_t oldest_sample() const { return oldest_sample_; }
  std::int64_t end_sample() const { return end_sample_; }
  std::int64_t write_errors() const { return write_errors_; }
  std::int64_t read_errors() const { return read_errors_; }
  int last_errno() const { return last_errno_; }
  const std::filesystem::path& file() const { return file_; }
  int channels() const { return channels_; }

 private:
  // pwrite/pread of `frames` frames at ring slot of `sample`, wrapping. False on error.
  bool transfer(bool writing, std::int64_t sample, std::size_t frames, float* data);

  std::filesystem::path file_;
  int descriptor_ = -1;
  int channels_;
  std::int64_t capacity_frames_;
  std::int64_t oldest_sample_ = 0;
  std::int64_t end_sample_ = 0;
  bool empty_ = true;
  std::int64_t write_errors_ = 0;
  std::int64_t read_errors_ = 0;
  int last_errno_ = 0;
};

}  // namespace dronetrack::capture
