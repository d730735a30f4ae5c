#pragma once
// Streams a multichannel recording (WAV PCM16/24/32/float, FLAC, anything libsndfile reads) as
// fixed-size float blocks with sample-accurate timestamps, applying the array's channel map.
//
// Memory is flat: one file-sized block and one mapped block (none when the channel map takes
// every channel in order) are allocated at construction and reused; next() allocates nothing.
// The block's levels are measured when counters() is asked for them, not per block: a replay's
// nodes never ask (they meter each channel themselves), and it cost 3 % of a replay's CPU.
//
// Errors (std::runtime_error, one line "<file>: <what>") at construction: missing file, not
// audio, empty recording, channel_map index outside the file's channels, and a truncated file
// whose header declares more frames than the data holds (checked at open for WAV, RF64, AIFF,
// W64, CAF and AU with a fixed-size encoding, where the header's declared length can be compared
// with the file size: capture/container_extent.hpp). A truncation only discovered
// while reading (e.g. FLAC, whose STREAMINFO frame count cannot be checked without decoding)
// is logged as an error with the same message, the frames that were present are delivered, the
// stream ends there and truncated() becomes true: by then consumers hold state worth flushing.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "capture/audio_source.hpp"

struct sf_private_tag;  // libsndfile's SNDFILE, kept out of this header

namespace dronetrack::capture {

class RecordingSource : public AudioSource {
 public:
  // channel_map[mic] = channel of the file that mic i was recorded on; empty = identity.
  RecordingSource(const std::filesystem::path& file, std::vector<int> channel_map,
                  std::size_t block_frames);
  ~RecordingSource() override;
  RecordingSource(const RecordingSource&) = delete;
  RecordingSource& operator=(const RecordingSource&) = delete;

  bool next(doa::AudioBlockView& block) override;
  double sample_rate_hz() const override { return sample_rate_hz_; }
  int channels() const override { return static_cast<int>(channel_map_.size()); }
  const SourceCounters& counters() const override;
  std::string describe() const override { return file_.string(); }

  std::int64_t total_frames() const { return total_frames_; }  // as the header declares
  int file_channels() const { return file_channels_; }
  std::int64_t frames_delivered() const { return position_; }
  // True once a read came up short before the declared end (see the header comment).
  bool truncated() const { return truncated_; }
  bool cut_short() const override { return truncated_; }

 private:
  std::filesystem::path file_;
  sf_private_tag* handle_ = nullptr;
  std::vector<int> channel_map_;
  std::size_t block_frames_ = 0;
  int file_channels_ = 0;
  double sample_rate_hz_ = 0.0;
  std::int64_t total_frames_ = 0;
  std::int64_t position_ = 0;  // frames delivered so far = first_sample of the next block
  bool truncated_ = false;
  bool ended_ = false;
  std::vector<float> file_block_;    // block_frames x file channels, as read
  std::vector<float> mapped_block_;  // block_frames x mics, as delivered (empty: file_block_ is)
  mutable SourceCounters counters_;  // levels filled in by counters() for the last block
  const float* last_block_ = nullptr;
  mutable std::size_t last_block_samples_ = 0;  // 0: levels measured (or no block yet)
};

}  // namespace dronetrack::capture
