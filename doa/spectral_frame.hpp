#pragma once
// Framing and the multichannel FFT stage of an array node.
//   Framer:          interleaved blocks in -> overlapping per-channel frames out (frame/hop),
//                    NaN/Inf replaced by 0 and counted, clipping counted, stream gaps detected.
//   MultichannelFft: one Hann-windowed real FFT per channel per frame (FFTW plan made once).
// Both preallocate everything in their constructors; the per-frame path allocates nothing.
#include <algorithm>
#include <complex>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "doa/audio_block.hpp"

namespace dronetrack::doa {

// One analysis frame: `channels` runs of `length` samples, channel-major.
struct FrameView {
  std::int64_t first_sample = 0;
  int channels = 0;
  int length = 0;
  const double* samples = nullptr;  // channel c at samples + c * stride (stride 0: length)
  int non_finite_samples = 0;       // in this frame, all channels (already replaced by 0)
  int clipped_samples = 0;          // in this frame, all channels
  double recent_mean_square = 0.0;  // of the samples new since the previous frame (level meter)
  std::ptrdiff_t stride = 0;        // distance between channels' first samples; 0 means `length`
  const double* channel(int c) const {
    return samples + static_cast<std::ptrdiff_t>(c) * (stride > 0 ? stride : length);
  }
};

struct FramerCounters {
  std::int64_t non_finite_samples = 0;
  std::int64_t clipped_samples = 0;
  std::int64_t stream_gaps = 0;      // blocks whose first_sample did not follow the previous one
  std::int64_t rejected_blocks = 0;  // wrong channel count or null data
};

// Each channel's samples sit in a buffer of two frame lengths; a frame is a window into it that
// moves by a hop, so the overlap is not shifted per hop. Only when the next block would run past
// the end are the buffered samples moved back to the start (every few frames).
class Framer {
 public:
  Framer(int channels, int frame_length, int hop);
  // Calls on_frame(const FrameView&) for every frame completed by this block.
  template <class OnFrame>
  void push(const AudioBlockView& block, OnFrame&& on_frame);
  // The same, and every sample of the block is shown to `observer` once, run by run, with the
  // statistics the framer's pass made: observer.run_limit() says how many frames the next run
  // may hold at most (where its own bookkeeping turns over), observer.observe(const ChannelRun&)
  // takes each run before the frame it completes is handed out. A block the framer rejects is
  // not shown.
  template <class OnFrame, class Observer>
  void push(const AudioBlockView& block, OnFrame&& on_frame, Observer& observer);
  const FramerCounters& counters() const { return counters_; }
  void reset();

 private:
  bool accept_block(const AudioBlockView& block);
  void restart();
  // Copies `count` frames of the block (all channels) behind what is buffered.
  void append_run(const AudioBlockView& block, std::size_t first, std::size_t count);
  void compact();
  FrameView emit_and_shift_view();
  void shift();

  int channels_;
  int length_;
  int hop_;
  int capacity_;   // samples per channel in the buffer
  int start_ = 0;  // buffer index of the oldest buffered sample
  int filled_ = 0;
  std::int64_t buffer_first_sample_ = 0;
  std::int64_t expected_next_sample_ = -1;
  std::vector<double> samples_;      // channels_ x capacity_
  std::vector<std::uint8_t> flags_;  // per buffer index: bit0 non-finite, bit1 clipped
  std::vector<double> run_sums_;     // per channel, of the last run appended (raw samples)
  std::vector<double> run_squares_;
  std::vector<double> run_peaks_;
  int flagged_non_finite_ = 0;  // buffered time indices with bit0 set
  int flagged_clipped_ = 0;     // buffered time indices with bit1 set
  double recent_sum_squares_ = 0.0;
  std::int64_t recent_values_ = 0;
  FramerCounters counters_;
};

template <class OnFrame>
void Framer::push(const AudioBlockView& block, OnFrame&& on_frame) {
  struct Nobody {
    static std::size_t run_limit() { return static_cast<std::size_t>(-1); }
    static void observe(const ChannelRun&) {}
  } nobody;
  push(block, std::forward<OnFrame>(on_frame), nobody);
}

template <class OnFrame, class Observer>
void Framer::push(const AudioBlockView& block, OnFrame&& on_frame, Observer& observer) {
  if (!accept_block(block)) return;
  std::size_t frame = 0;
  while (frame < block.frames) {
    const std::size_t count =
        std::min({block.frames - frame, static_cast<std::size_t>(length_ - filled_),
                  std::max<std::size_t>(observer.run_limit(), 1)});
    append_run(block, frame, count);
    observer.observe(ChannelRun{block.interleaved + frame * static_cast<std::size_t>(channels_),
                                count, channels_,
                                block.first_sample + static_cast<std::int64_t>(frame),
                                run_sums_.data(), run_squares_.data(), run_peaks_.data()});
    frame += count;
    if (filled_ == length_) {
      on_frame(emit_and_shift_view());
      shift();
    }
  }
}

// Hann window + r2c FFT of every channel; spectra are N/2+1 bins per channel.
class MultichannelFft {
 public:
  MultichannelFft(int channels, int frame_length, int fft_size);
  ~MultichannelFft();
  MultichannelFft(const MultichannelFft&) = delete;
  MultichannelFft& operator=(const MultichannelFft&) = delete;

  void process(const FrameView& frame);
  // From then on each channel's spectrum has its delay (samples, may be fractional) and gain
  // (dB) undone: X_c(k) * 10^(-gain/20) * exp(+j 2 pi k delay / fft_size). One entry per
  // channel; both empty: none.
  void set_channel_corrections(const std::vector<double>& delay_samples,
                               const std::vector<double>& gain_db);
  const std::complex<double>* spectrum(int channel) const;
  int fft_size() const { return fft_size_; }
  int bin_count() const { return fft_size_ / 2 + 1; }
  int channels() const { return channels_; }
  int frame_length() const { return frame_length_; }
  // Sum of squared window samples: turns |X|^2 into power per sample.
  double window_energy() const { return window_energy_; }
  // How much less a mean over frames `hop` samples apart tells than one over as many
  // independent frames: 1 + 2 sum_k c_k^2, c_k the window's overlap with itself k hops later
  // (normalised to 1 at k = 0). A frame's TDOA error is linear in the noise under the window,
  // so neighbours share c_k^2 of it. Hann at 0.17 s frames, 0.05 s hop: 1.64; hop >= frame: 1.
  double overlap_variance_factor(int hop) const;

 private:
  struct Plan;
  int channels_;
  int frame_length_;
  int fft_size_;
  int stride_;
  double window_energy_ = 0.0;
  std::vector<double> window_;
  std::vector<std::complex<double>> corrections_;  // channels x bins; empty: none
  std::unique_ptr<Plan> plan_;
};

// The smallest FFT size >= n of the form 2^a 3^b 5^c (FFTW is fast on those), preferring a
// power of two when it is within 12.5 % (power-of-two codelets are the fastest).
int fftw_friendly_size(int n);

}  // namespace dronetrack::doa
