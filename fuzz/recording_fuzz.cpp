// A recording file (WAV, RF64, AIFF, W64, CAF, AU, FLAC, anything libsndfile opens) through
// our reader: probe_recording, then RecordingSource (libsndfile plus our own container-length
// check, capture/container_extent.cpp) read to its end. Properties: a bad file is one
// std::runtime_error line, and the blocks delivered stay within what was asked for.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "capture/recording_info.hpp"
#include "capture/recording_source.hpp"
#include "common/log.hpp"
#include "doa/audio_block.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

constexpr std::size_t kBlockFrames = 256;
// A few bytes of a compressed format can declare hours of audio; reading a few seconds' worth
// covers the decode path without turning a valid file into a timeout.
constexpr std::int64_t kMaxFramesRead = 1 << 16;

void check_one_line(const std::runtime_error& error) {
  const std::string message = error.what();
  if (message.empty() || message.find('\n') != std::string::npos)
    dronetrack::fuzz::fail("recording error is not one line");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static dronetrack::fuzz::MemoryFile file;
  static const bool quiet = [] {
    dronetrack::log::set_level(dronetrack::log::Level::off);  // truncation is logged per input
    return true;
  }();
  (void)quiet;
  const std::string& path = file.write(data, size);
  try {
    (void)dronetrack::capture::probe_recording(path);
  } catch (const std::runtime_error& error) {
    check_one_line(error);
  }
  try {
    dronetrack::capture::RecordingSource source(path, {}, kBlockFrames);
    dronetrack::doa::AudioBlockView block;
    std::int64_t expected_first = 0;
    while (source.frames_delivered() < kMaxFramesRead && source.next(block)) {
      if (block.frames == 0 || block.frames > kBlockFrames ||
          block.first_sample != expected_first || block.channels != source.channels())
        dronetrack::fuzz::fail("block outside what was asked for");
      // Every delivered sample is read: a short buffer is an ASan error here.
      float sum = 0.0F;
      for (std::size_t i = 0; i < block.frames * static_cast<std::size_t>(block.channels); ++i)
        sum += block.interleaved[i];
      (void)sum;
      expected_first += static_cast<std::int64_t>(block.frames);
    }
  } catch (const std::runtime_error& error) {
    check_one_line(error);
  }
  return 0;
}
