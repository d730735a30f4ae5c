#pragma once
// Live multichannel input from a PortAudio device, with the same block interface as a
// recording.
//
// Threading: PortAudio's callback thread only copies each device buffer (exactly block_frames
// frames, PortAudio adapts the host's buffer size to that) into the next free slot of a
// lock-free SPSC ring and stamps it with its first sample index. The consumer's next() takes
// the oldest slot, applies the channel map and updates the counters.
// When the ring is full the callback drops the buffer and counts an overrun; the sample index
// still advances, so timestamps after a gap stay right (first_sample jumps).
//
// Errors: constructor throws std::runtime_error with one line (no such device, too few input
// channels, unsupported rate). next() returns false once request_stop() was called or the
// stream has stopped by itself, and throws if no block arrives within the timeout while the
// stream claims to be running (a stalled device must not hang a node silently).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "capture/audio_source.hpp"
#include "capture/portaudio_session.hpp"
#include "capture/spsc_ring.hpp"

namespace dronetrack::capture {

// The block a live node and `record` capture in: 20 ms (the pipeline's hop is a few of them),
// at least 64 frames.
inline std::size_t live_block_frames(double sample_rate_hz) {
  return static_cast<std::size_t>(std::max(64.0, std::round(0.02 * sample_rate_hz)));
}

struct PortAudioOptions {
  int device_index = -1;  // PortAudio index (see `dronetrack devices`); -1 = default input
  int mics = 0;           // the array's channel count; 0 = the size of channel_map
  // channel_map[mic] = device input channel of mic i; empty = identity over `mics`.
  std::vector<int> channel_map;
  double sample_rate_hz = 48000.0;
  std::size_t block_frames = 1024;
  std::size_t ring_blocks = 64;             // how late the consumer may fall behind before overruns
  std::chrono::milliseconds timeout{2000};  // next() waits this long for a block
};

class PortAudioSource : public AudioSource {
 public:
  // Opens and starts the stream.
  explicit PortAudioSource(PortAudioOptions options);
  ~PortAudioSource() override;
  PortAudioSource(const PortAudioSource&) = delete;
  PortAudioSource& operator=(const PortAudioSource&) = delete;

  bool next(doa::AudioBlockView& block) override;
  double sample_rate_hz() const override { return options_.sample_rate_hz; }
  int channels() const override { return static_cast<int>(options_.channel_map.size()); }
  const SourceCounters& counters() const override { return counters_; }
  std::string describe() const override { return description_; }

  // Unix time (system clock, seconds) of sample 0, so a block's time is
  // stream_start_unix_s() + first_sample / sample_rate_hz(). Taken when the stream starts and
  // refined by the first callback (its arrival minus one block); accurate to the device's
  // input latency, a few milliseconds.
  double stream_start_unix_s() const;
  int device_channels() const { return device_channels_; }
  // Thread-safe: makes a pending or later next() return false; the stream is stopped.
  void request_stop() { stop_requested_.store(true, std::memory_order_relaxed); }

  // The callback's state, shared with PortAudio's thread (public only so the C callback in the
  // .cpp can name it).
  struct Block {
    std::int64_t first_sample = 0;
    std::size_t frames = 0;
    std::vector<float> interleaved;  // block_frames x device channels, as captured
  };
  struct CallbackState {
    CallbackState(std::size_t ring_blocks, const Block& prototype) : ring(ring_blocks, prototype) {}
    SpscRing<Block> ring;
    std::size_t block_frames = 0;
    int device_channels = 0;
    double sample_rate_hz = 0.0;
    std::int64_t next_first_sample = 0;  // callback thread only
    std::atomic<std::int64_t> dropped_blocks{0};
    std::atomic<std::int64_t> device_overflows{0};
    std::atomic<std::int64_t> blocks_seen{0};
    std::atomic<double> first_callback_unix_s{0.0};
  };

 private:
  PortAudioOptions options_;
  PortAudioSession session_;  // before stream_: terminated after the stream is closed
  std::unique_ptr<CallbackState> state_;
  void* stream_ = nullptr;  // PaStream*
  int device_channels_ = 0;
  std::string description_;
  double start_unix_s_ = 0.0;
  std::atomic<bool> stop_requested_{false};
  bool ended_ = false;
  std::vector<float> mapped_block_;  // block_frames x mics, as delivered
  SourceCounters counters_;
  std::chrono::steady_clock::time_point last_overrun_log_{};
  std::int64_t logged_overruns_ = 0;

  void close_stream();
};

}  // namespace dronetrack::capture
