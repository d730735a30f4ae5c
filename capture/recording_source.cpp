#include "capture/recording_source.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include <sndfile.h>

#include "capture/block_mapping.hpp"
#include "capture/container_extent.hpp"
#include "common/log.hpp"

namespace dronetrack::capture {
namespace {

std::runtime_error file_error(const std::filesystem::path& file, const std::string& what) {
  return std::runtime_error(file.string() + ": " + what);
}

std::string truncation_message(std::int64_t declared_frames, std::int64_t data_end_frame) {
  return "truncated: header declares " + std::to_string(declared_frames) +
         " frames, data ends at frame " + std::to_string(data_end_frame);
}

// Bytes per frame of a fixed-size encoding; 0 for compressed ones (never checked at open).
int bytes_per_frame(const SF_INFO& info) {
  int bytes = 0;
  switch (info.format & SF_FORMAT_SUBMASK) {
    case SF_FORMAT_PCM_S8:
    case SF_FORMAT_PCM_U8:
    case SF_FORMAT_ULAW:
    case SF_FORMAT_ALAW:
      bytes = 1;
      break;
    case SF_FORMAT_PCM_16:
      bytes = 2;
      break;
    case SF_FORMAT_PCM_24:
      bytes = 3;
      break;
    case SF_FORMAT_PCM_32:
    case SF_FORMAT_FLOAT:
      bytes = 4;
      break;
    case SF_FORMAT_DOUBLE:
      bytes = 8;
      break;
    default:
      return 0;
  }
  return bytes * info.channels;
}

}  // namespace

RecordingSource::RecordingSource(const std::filesystem::path& file, std::vector<int> channel_map,
                                 std::size_t block_frames)
    : file_(file), channel_map_(std::move(channel_map)), block_frames_(block_frames) {
  if (block_frames_ == 0) throw file_error(file_, "block size must be at least 1 frame");
  std::error_code error;
  if (!std::filesystem::exists(file_, error)) throw file_error(file_, "recording not found");
  if (std::filesystem::is_directory(file_, error)) {
    throw file_error(file_, "is a directory, not a recording");
  }

  SF_INFO info{};
  handle_ = sf_open(file_.c_str(), SFM_READ, &info);
  if (handle_ == nullptr) {
    throw file_error(file_, std::string("cannot read as audio (") + sf_strerror(nullptr) + ")");
  }
  // From here on the destructor will not run if we throw: close explicitly.
  try {
    file_channels_ = info.channels;
    sample_rate_hz_ = info.samplerate;
    total_frames_ = info.frames;
    if (total_frames_ <= 0) throw file_error(file_, "empty recording (0 frames)");
    // libsndfile reports the frames present; the container's header says what was meant.
    if (const auto extent = data_extent(file_, bytes_per_frame(info));
        extent && extent->present_frames < extent->declared_frames) {
      throw file_error(file_, truncation_message(extent->declared_frames, extent->present_frames));
    }
    if (channel_map_.empty()) {
      channel_map_.resize(static_cast<std::size_t>(file_channels_));
      for (int channel = 0; channel < file_channels_; ++channel) {
        channel_map_[static_cast<std::size_t>(channel)] = channel;
      }
    }
    for (std::size_t mic = 0; mic < channel_map_.size(); ++mic) {
      const int channel = channel_map_[mic];
      if (channel < 0 || channel >= file_channels_) {
        throw file_error(file_, "channel_map[" + std::to_string(mic) +
                                    "] = " + std::to_string(channel) + " but the recording has " +
                                    std::to_string(file_channels_) + " channels (0.." +
                                    std::to_string(file_channels_ - 1) + ")");
      }
    }
  } catch (...) {
    sf_close(handle_);
    handle_ = nullptr;
    throw;
  }
  file_block_.assign(block_frames_ * static_cast<std::size_t>(file_channels_), 0.0F);
  // Every channel in order (the usual case): the block read is the block delivered, no copy.
  if (!is_identity_map(channel_map_, static_cast<std::size_t>(file_channels_)))
    mapped_block_.assign(block_frames_ * channel_map_.size(), 0.0F);
}

RecordingSource::~RecordingSource() {
  if (handle_ != nullptr) sf_close(handle_);
}

bool RecordingSource::next(doa::AudioBlockView& block) {
  if (ended_ || position_ >= total_frames_) {
    ended_ = true;
    return false;
  }
  const auto wanted = static_cast<sf_count_t>(
      std::min<std::int64_t>(static_cast<std::int64_t>(block_frames_), total_frames_ - position_));
  const sf_count_t got = sf_readf_float(handle_, file_block_.data(), wanted);
  if (got < wanted) {
    // The header promised more: deliver what is there, then end (see the header comment).
    truncated_ = true;
    ended_ = true;
    log::error(file_.string(), ": ", truncation_message(total_frames_, position_ + got));
    if (got <= 0) return false;
  }

  const auto frames = static_cast<std::size_t>(got);
  const float* delivered = file_block_.data();
  if (!mapped_block_.empty()) {
    map_channels(file_block_.data(), frames, static_cast<std::size_t>(file_channels_), channel_map_,
                 mapped_block_.data());
    delivered = mapped_block_.data();
  }
  last_block_ = delivered;
  last_block_samples_ = frames * channel_map_.size();

  block.first_sample = position_;
  block.channels = channels();
  block.frames = frames;
  block.interleaved = delivered;
  position_ += got;
  return true;
}

const SourceCounters& RecordingSource::counters() const {
  if (last_block_samples_ > 0) {
    measure_levels(last_block_, last_block_samples_, counters_);
    last_block_samples_ = 0;
  }
  return counters_;
}

}  // namespace dronetrack::capture
