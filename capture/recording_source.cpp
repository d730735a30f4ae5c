#include "capture/recording_source.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <optional>
#include <stdexcept>

#include <sndfile.h>

#include "capture/block_mapping.hpp"
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

std::uint32_t read_le32(const unsigned char* bytes) {
  return static_cast<std::uint32_t>(bytes[0]) | (static_cast<std::uint32_t>(bytes[1]) << 8) |
         (static_cast<std::uint32_t>(bytes[2]) << 16) |
         (static_cast<std::uint32_t>(bytes[3]) << 24);
}

struct DataChunkExtent {
  std::int64_t declared_frames = 0;
  std::int64_t present_frames = 0;
};

// libsndfile quietly shortens a RIFF WAV whose data chunk claims more bytes than the file holds,
// so a recorder that died mid-write would look like a complete, shorter file. Walk the chunks
// ourselves to compare the declared data size with what is on disk. Returns nothing when the
// file is not plain RIFF/WAVE or uses a streaming placeholder size (0 or 0xFFFFFFFF).
std::optional<DataChunkExtent> riff_data_extent(const std::filesystem::path& file) {
  std::error_code error;
  const auto file_size = static_cast<std::int64_t>(std::filesystem::file_size(file, error));
  if (error) return std::nullopt;
  std::ifstream in(file, std::ios::binary);
  std::array<unsigned char, 12> riff{};
  if (!in.read(reinterpret_cast<char*>(riff.data()), riff.size())) return std::nullopt;
  if (std::memcmp(riff.data(), "RIFF", 4) != 0 || std::memcmp(riff.data() + 8, "WAVE", 4) != 0) {
    return std::nullopt;
  }
  std::int64_t offset = 12;
  std::uint32_t block_align = 0;
  while (offset + 8 <= file_size) {
    std::array<unsigned char, 8> header{};
    in.seekg(offset);
    if (!in.read(reinterpret_cast<char*>(header.data()), header.size())) return std::nullopt;
    const std::uint32_t size = read_le32(header.data() + 4);
    if (std::memcmp(header.data(), "fmt ", 4) == 0 && size >= 14) {
      std::array<unsigned char, 14> fmt{};
      if (!in.read(reinterpret_cast<char*>(fmt.data()), fmt.size())) return std::nullopt;
      block_align =
          static_cast<std::uint32_t>(fmt[12]) | (static_cast<std::uint32_t>(fmt[13]) << 8);
    } else if (std::memcmp(header.data(), "data", 4) == 0) {
      if (block_align == 0 || size == 0 || size == 0xFFFFFFFFU) return std::nullopt;
      const std::int64_t present_bytes = file_size - (offset + 8);
      return DataChunkExtent{static_cast<std::int64_t>(size) / block_align,
                             std::min<std::int64_t>(size, present_bytes) / block_align};
    }
    offset += 8 + static_cast<std::int64_t>(size) + (size & 1U);  // chunks are word aligned
  }
  return std::nullopt;
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
    if (const auto extent = riff_data_extent(file_);
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
  map_channels_and_count(file_block_.data(), frames, static_cast<std::size_t>(file_channels_),
                         channel_map_, mapped_block_.data(), counters_);

  block.first_sample = position_;
  block.channels = channels();
  block.frames = frames;
  block.interleaved = mapped_block_.data();
  position_ += got;
  return true;
}

}  // namespace dronetrack::capture
