#include "capture/portaudio_source.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <thread>

#include <portaudio.h>

#include "capture/block_mapping.hpp"
#include "common/log.hpp"

namespace dronetrack::capture {
namespace {

double unix_now_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string rate_text(double rate_hz) {
  std::string text = std::to_string(rate_hz);
  text.erase(text.find_last_not_of('0') + 1);
  if (!text.empty() && text.back() == '.') text.pop_back();
  return text;
}

// Runs on PortAudio's audio thread: no locks, no allocation, no logging. It only copies.
int capture_callback(const void* input, void* /*output*/, unsigned long frame_count,
                     const PaStreamCallbackTimeInfo* /*time_info*/,
                     PaStreamCallbackFlags status_flags, void* user_data) {
  auto& state = *static_cast<PortAudioSource::CallbackState*>(user_data);
  if ((status_flags & paInputOverflow) != 0) {
    state.device_overflows.fetch_add(1, std::memory_order_relaxed);
  }
  if (state.blocks_seen.load(std::memory_order_relaxed) == 0) {
    // The block's first sample was captured about one block before the callback ran.
    state.first_callback_unix_s.store(
        unix_now_s() - static_cast<double>(frame_count) / state.sample_rate_hz,
        std::memory_order_relaxed);
  }
  state.blocks_seen.fetch_add(1, std::memory_order_release);

  PortAudioSource::Block* slot = state.ring.try_begin_write();
  if (slot == nullptr) {
    state.dropped_blocks.fetch_add(1, std::memory_order_relaxed);
  } else {
    // PortAudio delivers exactly the frames_per_buffer we asked for; clamp anyway so a host
    // that does not cannot write past the slot.
    const std::size_t frames = std::min<std::size_t>(frame_count, state.block_frames);
    const std::size_t values = frames * static_cast<std::size_t>(state.device_channels);
    slot->first_sample = state.next_first_sample;
    slot->frames = frames;
    if (input != nullptr) {
      std::memcpy(slot->interleaved.data(), input, values * sizeof(float));
    } else {
      std::fill_n(slot->interleaved.begin(), values, 0.0F);
    }
    state.ring.end_write();
  }
  state.next_first_sample += static_cast<std::int64_t>(frame_count);
  return paContinue;
}

}  // namespace

PortAudioSource::PortAudioSource(PortAudioOptions options) : options_(std::move(options)) {
  const std::string what = "PortAudio input: ";
  if (options_.block_frames == 0) throw std::runtime_error(what + "block size must be >= 1 frame");
  if (options_.ring_blocks == 0) throw std::runtime_error(what + "ring must hold >= 1 block");
  if (!(options_.sample_rate_hz > 0.0) || !std::isfinite(options_.sample_rate_hz)) {
    throw std::runtime_error(what + "sample rate must be a positive number of Hz");
  }
  std::vector<int>& map = options_.channel_map;
  if (map.empty()) {
    if (options_.mics <= 0) throw std::runtime_error(what + "the array needs at least 1 mic");
    for (int mic = 0; mic < options_.mics; ++mic) map.push_back(mic);
  } else if (options_.mics != 0 && static_cast<std::size_t>(options_.mics) != map.size()) {
    throw std::runtime_error(what + "channel_map has " + std::to_string(map.size()) +
                             " entries but the array has " + std::to_string(options_.mics) +
                             " mics");
  }
  for (std::size_t mic = 0; mic < map.size(); ++mic) {
    if (map[mic] < 0) {
      throw std::runtime_error(what + "channel_map[" + std::to_string(mic) +
                               "] = " + std::to_string(map[mic]) + " is not a channel");
    }
  }
  const int needed_channels = *std::max_element(map.begin(), map.end()) + 1;

  PaDeviceIndex device = options_.device_index;
  if (device < 0) {
    device = Pa_GetDefaultInputDevice();
    if (device == paNoDevice) {
      throw std::runtime_error(what + "no default input device (see `dronetrack devices`)");
    }
  } else if (device >= Pa_GetDeviceCount()) {
    throw std::runtime_error("device " + std::to_string(device) + " does not exist (there are " +
                             std::to_string(std::max(0, Pa_GetDeviceCount())) +
                             " devices; see `dronetrack devices`)");
  }
  const PaDeviceInfo* info = Pa_GetDeviceInfo(device);
  if (info == nullptr) {
    throw std::runtime_error("device " + std::to_string(device) + " cannot be queried");
  }
  description_ = "device " + std::to_string(device) + " (" + (info->name ? info->name : "") + ")";
  if (info->maxInputChannels < needed_channels) {
    throw std::runtime_error(description_ + " has " + std::to_string(info->maxInputChannels) +
                             " input channels, the array needs " + std::to_string(needed_channels));
  }
  device_channels_ = needed_channels;

  PaStreamParameters input{};
  input.device = device;
  input.channelCount = needed_channels;
  input.sampleFormat = paFloat32;  // interleaved
  // A DOA node has no use for low latency; a larger host buffer rides out scheduling hiccups.
  input.suggestedLatency = info->defaultHighInputLatency;
  input.hostApiSpecificStreamInfo = nullptr;
  const PaError supported = Pa_IsFormatSupported(&input, nullptr, options_.sample_rate_hz);
  if (supported != paFormatIsSupported) {
    throw std::runtime_error(description_ + " cannot capture " + std::to_string(needed_channels) +
                             " channels at " + rate_text(options_.sample_rate_hz) + " Hz (" +
                             Pa_GetErrorText(supported) + ")");
  }

  Block prototype;
  prototype.interleaved.assign(options_.block_frames * static_cast<std::size_t>(needed_channels),
                               0.0F);
  state_ = std::make_unique<CallbackState>(options_.ring_blocks, prototype);
  state_->block_frames = options_.block_frames;
  state_->device_channels = needed_channels;
  state_->sample_rate_hz = options_.sample_rate_hz;
  mapped_block_.assign(options_.block_frames * map.size(), 0.0F);

  PaStream* stream = nullptr;
  PaError error = Pa_OpenStream(&stream, &input, nullptr, options_.sample_rate_hz,
                                static_cast<unsigned long>(options_.block_frames), paNoFlag,
                                &capture_callback, state_.get());
  if (error != paNoError) {
    throw std::runtime_error(description_ + ": cannot open input stream (" +
                             Pa_GetErrorText(error) + ")");
  }
  stream_ = stream;
  start_unix_s_ = unix_now_s();
  error = Pa_StartStream(stream);
  if (error != paNoError) {
    close_stream();
    throw std::runtime_error(description_ + ": cannot start input stream (" +
                             Pa_GetErrorText(error) + ")");
  }
  log::info(description_, ": capturing ", needed_channels, " channels at ",
            rate_text(options_.sample_rate_hz), " Hz in blocks of ", options_.block_frames,
            " frames");
}

PortAudioSource::~PortAudioSource() { close_stream(); }

void PortAudioSource::close_stream() {
  if (stream_ == nullptr) return;
  auto* stream = static_cast<PaStream*>(stream_);
  // Abort rather than stop: there is no output to drain and the callback must end now.
  Pa_AbortStream(stream);
  Pa_CloseStream(stream);
  stream_ = nullptr;
}

double PortAudioSource::stream_start_unix_s() const {
  if (state_ && state_->blocks_seen.load(std::memory_order_acquire) > 0) {
    return state_->first_callback_unix_s.load(std::memory_order_relaxed);
  }
  return start_unix_s_;
}

bool PortAudioSource::next(doa::AudioBlockView& block) {
  if (ended_) return false;
  const auto deadline = std::chrono::steady_clock::now() + options_.timeout;
  // Sleep a small fraction of a block between polls: the callback cannot signal us without a
  // system call, which it must not make.
  const auto poll_interval = std::chrono::duration<double>(
      std::min(0.001, 0.25 * static_cast<double>(options_.block_frames) / options_.sample_rate_hz));
  Block* slot = nullptr;
  while (true) {
    if (stop_requested_.load(std::memory_order_relaxed)) {
      ended_ = true;
      close_stream();
      return false;
    }
    slot = state_->ring.try_begin_read();
    if (slot != nullptr) break;
    if (Pa_IsStreamActive(static_cast<PaStream*>(stream_)) != 1) {
      ended_ = true;
      log::error(description_, ": input stream stopped");
      close_stream();
      return false;
    }
    if (std::chrono::steady_clock::now() > deadline) {
      throw std::runtime_error(description_ + ": no audio for " +
                               std::to_string(options_.timeout.count()) + " ms (device stalled?)");
    }
    std::this_thread::sleep_for(poll_interval);
  }

  const std::size_t frames = slot->frames;
  map_channels_and_count(slot->interleaved.data(), frames,
                         static_cast<std::size_t>(device_channels_), options_.channel_map,
                         mapped_block_.data(), counters_);
  block.first_sample = slot->first_sample;
  block.channels = channels();
  block.frames = frames;
  block.interleaved = mapped_block_.data();
  state_->ring.end_read();  // copied out: the callback may reuse the slot

  const std::int64_t overruns = state_->dropped_blocks.load(std::memory_order_relaxed) +
                                state_->device_overflows.load(std::memory_order_relaxed);
  if (overruns > counters_.overruns) {
    // At most one line a second: an overloaded machine must not also drown in log lines.
    const auto now = std::chrono::steady_clock::now();
    if (now - last_overrun_log_ >= std::chrono::seconds(1)) {
      log::warn(description_, ": ", overruns - logged_overruns_,
                " input block(s) lost (consumer late or device overflow), ", overruns, " in all");
      last_overrun_log_ = now;
      logged_overruns_ = overruns;
    }
  }
  counters_.overruns = overruns;
  return true;
}

}  // namespace dronetrack::capture
