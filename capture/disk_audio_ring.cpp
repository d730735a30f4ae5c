#include "capture/disk_audio_ring.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace dronetrack::capture {

DiskAudioRing::DiskAudioRing(const std::filesystem::path& file, int channels,
                             std::int64_t capacity_frames)
    : file_(file), channels_(channels), capacity_frames_(capacity_frames) {
  if (channels < 1 || capacity_frames < 1)
    throw std::runtime_error(file.string() + ": an audio ring needs channels and frames");
  descriptor_ = ::open(file.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
  if (descriptor_ < 0)
    throw std::runtime_error(file.string() + ": cannot create the audio ring (" +
                             std::strerror(errno) + ")");
  // The whole size up front: a disk too small for the ring is said now, not mid-incident.
  const auto bytes =
      static_cast<off_t>(capacity_frames) * channels * static_cast<off_t>(sizeof(float));
  const int reserved = ::posix_fallocate(descriptor_, 0, bytes);
  // Other failures (a file system or device without fallocate) are left to the writes to tell.
  if (reserved == ENOSPC || reserved == EFBIG || reserved == EDQUOT) {
    ::close(descriptor_);
    descriptor_ = -1;
    throw std::runtime_error(file.string() + ": cannot reserve " + std::to_string(bytes) +
                             " bytes for the audio ring (" + std::strerror(reserved) + ")");
  }
}

DiskAudioRing::~DiskAudioRing() {
  if (descriptor_ >= 0) ::close(descriptor_);
}

bool DiskAudioRing::transfer(bool writing, std::int64_t sample, std::size_t frames, float* data) {
  const std::size_t frame_bytes = static_cast<std::size_t>(channels_) * sizeof(float);
  std::size_t done = 0;
  while (done < frames) {
    const std::int64_t slot = (sample + static_cast<std::int64_t>(done)) % capacity_frames_;
    const std::size_t run =
        std::min(frames - done, static_cast<std::size_t>(capacity_frames_ - slot));
    auto* bytes = reinterpret_cast<char*>(data + done * static_cast<std::size_t>(channels_));
    std::size_t left = run * frame_bytes;
    off_t offset = static_cast<off_t>(slot) * static_cast<off_t>(frame_bytes);
    while (left > 0) {
      const ssize_t moved = writing ? ::pwrite(descriptor_, bytes, left, offset)
                                    : ::pread(descriptor_, bytes, left, offset);
      if (moved < 0 && errno == EINTR) continue;
      if (moved <= 0) {
        last_errno_ = moved < 0 ? errno : EIO;
        return false;
      }
      bytes += moved;
      offset += moved;
      left -= static_cast<std::size_t>(moved);
    }
    done += run;
  }
  return true;
}

void DiskAudioRing::append(const doa::AudioBlockView& block) {
  if (block.frames == 0) return;
  // A gap in the stream: what is held no longer runs up to this block.
  if (empty_ || block.first_sample != end_sample_) oldest_sample_ = block.first_sample;
  empty_ = false;
  // pwrite takes a non-const buffer only through this cast; the samples are not changed.
  if (!transfer(true, block.first_sample, block.frames, const_cast<float*>(block.interleaved))) {
    ++write_errors_;
    oldest_sample_ = block.first_sample + static_cast<std::int64_t>(block.frames);
  }
  end_sample_ = block.first_sample + static_cast<std::int64_t>(block.frames);
  oldest_sample_ = std::max(oldest_sample_, end_sample_ - capacity_frames_);
}

bool DiskAudioRing::read(std::int64_t first_sample, std::size_t frames, float* interleaved) {
  if (first_sample < oldest_sample_ ||
      first_sample + static_cast<std::int64_t>(frames) > end_sample_ || empty_)
    return false;
  if (!transfer(false, first_sample, frames, interleaved)) {
    ++read_errors_;
    return false;
  }
  return true;
}

}  // namespace dronetrack::capture
