#include "doa/spectral_frame.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <string>

#include "doa/fftw_lock.hpp"
#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

std::mutex& fftw_planner_mutex() {
  static std::mutex mutex;
  return mutex;
}

namespace {
constexpr double kClipLevel = 0.999;
constexpr std::uint8_t kFlagNonFinite = 1;
constexpr std::uint8_t kFlagClipped = 2;

// Deinterleaves `count` frames into each channel's run (channel c at target + c * stride) and
// adds each channel's sum, sum of squares and peak to sums[c], squares[c], peaks[c] (zero
// before). kChannels 4: the SIMD layer's kernel for whole vectors of frames, the rest (fewer
// than a vector's frames) below; 0: any count, channel by channel, four partial sums (one
// running sum would make every sample wait for the previous addition).
template <int kChannels>
void deinterleave(const float* source, int channels, int count, double* target,
                  std::ptrdiff_t stride, double* sums, double* squares, double* peaks) {
  if constexpr (kChannels == 4) {
    // Whole vectors of the SIMD target first (doa/simd), the rest below.
    const int done = simd::deinterleave_four({source, count, target, stride, sums, squares, peaks});
    source += done * 4;
    target += done;
    count -= done;
  }
  for (int c = 0; c < channels; ++c) {
    double* run = target + c * stride;
    double sum[4] = {0.0, 0.0, 0.0, 0.0};
    double square[4] = {0.0, 0.0, 0.0, 0.0};
    double peak[4] = {0.0, 0.0, 0.0, 0.0};
    int n = 0;
    for (; n + 4 <= count; n += 4) {
      for (int lane = 0; lane < 4; ++lane) {
        const double value = source[(n + lane) * channels + c];
        run[n + lane] = value;
        sum[lane] += value;
        square[lane] += value * value;
        peak[lane] = std::max(peak[lane], std::fabs(value));
      }
    }
    for (; n < count; ++n) {
      const double value = source[n * channels + c];
      run[n] = value;
      sum[0] += value;
      square[0] += value * value;
      peak[0] = std::max(peak[0], std::fabs(value));
    }
    sums[c] += (sum[0] + sum[1]) + (sum[2] + sum[3]);
    squares[c] += (square[0] + square[1]) + (square[2] + square[3]);
    peaks[c] = std::max({peaks[c], peak[0], peak[1], peak[2], peak[3]});
  }
}
}  // namespace

Framer::Framer(int channels, int frame_length, int hop)
    : channels_(channels), length_(frame_length), hop_(hop), capacity_(4 * frame_length) {
  if (channels < 1) throw std::invalid_argument("Framer: channels must be >= 1");
  if (frame_length < 2) throw std::invalid_argument("Framer: frame_length must be >= 2");
  if (hop < 1 || hop > frame_length)
    throw std::invalid_argument("Framer: hop must be in [1, frame_length]");
  samples_.assign(static_cast<std::size_t>(channels) * static_cast<std::size_t>(capacity_), 0.0);
  flags_.assign(static_cast<std::size_t>(capacity_), 0);
  run_sums_.assign(static_cast<std::size_t>(channels), 0.0);
  run_squares_.assign(static_cast<std::size_t>(channels), 0.0);
  run_peaks_.assign(static_cast<std::size_t>(channels), 0.0);
}

void Framer::reset() {
  restart();
  expected_next_sample_ = -1;
}

void Framer::restart() {
  filled_ = 0;
  flagged_non_finite_ = 0;
  flagged_clipped_ = 0;
}

bool Framer::accept_block(const AudioBlockView& block) {
  if (block.channels != channels_ || (block.frames > 0 && block.interleaved == nullptr)) {
    ++counters_.rejected_blocks;
    return false;
  }
  if (block.frames == 0) return true;
  if (expected_next_sample_ >= 0 && block.first_sample != expected_next_sample_) {
    // A gap or a rewind: samples on both sides do not belong to one frame. Start over.
    ++counters_.stream_gaps;
    restart();
  }
  if (filled_ == 0) buffer_first_sample_ = block.first_sample;
  expected_next_sample_ = block.first_sample + static_cast<std::int64_t>(block.frames);
  return true;
}

void Framer::compact() {
  for (int c = 0; c < channels_; ++c) {
    double* run = samples_.data() + static_cast<std::ptrdiff_t>(c) * capacity_;
    std::memmove(run, run + start_, static_cast<std::size_t>(filled_) * sizeof(double));
  }
  std::memmove(flags_.data(), flags_.data() + start_, static_cast<std::size_t>(filled_));
  start_ = 0;
}

void Framer::append_run(const AudioBlockView& block, std::size_t first, std::size_t count) {
  const int frames = static_cast<int>(count);
  if (filled_ == 0) start_ = 0;
  if (start_ + filled_ + frames > capacity_) compact();
  const int position = start_ + filled_;
  std::uint8_t* flags = flags_.data() + position;
  std::fill_n(flags, frames, std::uint8_t{0});
  const float* source = block.interleaved + first * static_cast<std::size_t>(channels_);
  double* target = samples_.data() + position;
  std::fill(run_sums_.begin(), run_sums_.end(), 0.0);
  std::fill(run_squares_.begin(), run_squares_.end(), 0.0);
  std::fill(run_peaks_.begin(), run_peaks_.end(), 0.0);
  if (channels_ == 4) {
    deinterleave<4>(source, 4, frames, target, capacity_, run_sums_.data(), run_squares_.data(),
                    run_peaks_.data());
  } else {
    deinterleave<0>(source, channels_, frames, target, capacity_, run_sums_.data(),
                    run_squares_.data(), run_peaks_.data());
  }
  // A float squared cannot overflow a double, so a channel's squares are finite exactly when
  // its samples are: no per-sample test unless a sum or a peak says so.
  double sum_squares = 0.0;
  bool odd = false;
  for (int c = 0; c < channels_; ++c) {
    const auto index = static_cast<std::size_t>(c);
    sum_squares += run_squares_[index];
    odd = odd || !std::isfinite(run_squares_[index]) || !(run_peaks_[index] < kClipLevel);
  }
  if (odd) {
    // Rare: redo the run sample by sample to replace and count.
    sum_squares = 0.0;
    for (int c = 0; c < channels_; ++c) {
      double* run = target + static_cast<std::ptrdiff_t>(c) * capacity_;
      for (int n = 0; n < frames; ++n) {
        double value = run[n];
        if (!std::isfinite(value)) {
          value = 0.0;
          run[n] = 0.0;
          flagged_non_finite_ += (flags[n] & kFlagNonFinite) == 0 ? 1 : 0;
          flags[n] |= kFlagNonFinite;
          ++counters_.non_finite_samples;
        } else if (std::fabs(value) >= kClipLevel) {
          flagged_clipped_ += (flags[n] & kFlagClipped) == 0 ? 1 : 0;
          flags[n] |= kFlagClipped;
          ++counters_.clipped_samples;
        }
        sum_squares += value * value;
      }
    }
  }
  recent_sum_squares_ += sum_squares;
  recent_values_ += static_cast<std::int64_t>(count) * channels_;
  filled_ += frames;
}

FrameView Framer::emit_and_shift_view() {
  FrameView view;
  view.first_sample = buffer_first_sample_;
  view.channels = channels_;
  view.length = length_;
  view.samples = samples_.data() + start_;
  view.stride = capacity_;
  view.recent_mean_square =
      recent_values_ > 0 ? recent_sum_squares_ / static_cast<double>(recent_values_) : 0.0;
  recent_sum_squares_ = 0.0;
  recent_values_ = 0;
  view.non_finite_samples = flagged_non_finite_;
  view.clipped_samples = flagged_clipped_;
  return view;
}

void Framer::shift() {
  // The oldest hop leaves the frame, and its flags with it; nothing moves.
  if (flagged_non_finite_ + flagged_clipped_ > 0) {
    for (int n = start_; n < start_ + hop_; ++n) {
      flagged_non_finite_ -= (flags_[static_cast<std::size_t>(n)] & kFlagNonFinite) != 0 ? 1 : 0;
      flagged_clipped_ -= (flags_[static_cast<std::size_t>(n)] & kFlagClipped) != 0 ? 1 : 0;
    }
  }
  start_ += hop_;
  filled_ = length_ - hop_;
  buffer_first_sample_ += hop_;
}

int fftw_friendly_size(int n) {
  int power_of_two = 1;
  while (power_of_two < n) power_of_two *= 2;
  int best = power_of_two;
  for (int candidate = n; candidate < power_of_two; ++candidate) {
    int rest = candidate;
    for (const int factor : {2, 3, 5}) {
      while (rest % factor == 0) rest /= factor;
    }
    if (rest == 1) {
      best = candidate;
      break;
    }
  }
  return (static_cast<double>(power_of_two) <= 1.125 * best) ? power_of_two : best;
}

struct MultichannelFft::Plan {
  double* input = nullptr;         // fft_size, windowed frame then zeros
  fftw_complex* output = nullptr;  // channels x bins
  fftw_plan plan = nullptr;
};

MultichannelFft::MultichannelFft(int channels, int frame_length, int fft_size)
    : channels_(channels),
      frame_length_(frame_length),
      fft_size_(fft_size),
      // Every channel's spectrum starts 64-byte aligned, as FFTW's SIMD plan was made for.
      stride_((fft_size / 2 + 1 + 3) / 4 * 4),
      plan_(std::make_unique<Plan>()) {
  if (fft_size < frame_length || fft_size % 2 != 0)
    throw std::invalid_argument("MultichannelFft: fft_size must be even and >= frame_length (" +
                                std::to_string(fft_size) + " < " + std::to_string(frame_length) +
                                ")");
  window_.resize(static_cast<std::size_t>(frame_length));
  for (int n = 0; n < frame_length; ++n) {
    // Periodic-free symmetric Hann: zero at both ends, so frame edges do not leak.
    const double phase = 2.0 * std::numbers::pi * n / (frame_length - 1);
    window_[static_cast<std::size_t>(n)] = 0.5 - 0.5 * std::cos(phase);
    window_energy_ += window_[static_cast<std::size_t>(n)] * window_[static_cast<std::size_t>(n)];
  }
  const std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  plan_->input = fftw_alloc_real(static_cast<std::size_t>(fft_size));
  plan_->output =
      fftw_alloc_complex(static_cast<std::size_t>(channels) * static_cast<std::size_t>(stride_));
  if (plan_->input == nullptr || plan_->output == nullptr) throw std::bad_alloc();
  // FFTW_ESTIMATE: the same algorithm every run, so a replay is bit-for-bit repeatable, and
  // ~2 ms of planning instead of FFTW_MEASURE's ~0.25 s, whose timed choice differs between runs
  // and so changes the last bits of every result (docs/doa.md, "FFT plans").
  plan_->plan = fftw_plan_dft_r2c_1d(fft_size, plan_->input, plan_->output, FFTW_ESTIMATE);
  if (plan_->plan == nullptr) throw std::runtime_error("MultichannelFft: FFTW plan failed");
  std::fill_n(plan_->input, fft_size, 0.0);
}

MultichannelFft::~MultichannelFft() {
  if (!plan_) return;
  const std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  if (plan_->plan != nullptr) fftw_destroy_plan(plan_->plan);
  fftw_free(plan_->input);
  fftw_free(plan_->output);
}

void MultichannelFft::process(const FrameView& frame) {
  for (int c = 0; c < channels_; ++c) {
    const double* samples = frame.channel(c);
    for (int n = 0; n < frame_length_; ++n)
      plan_->input[n] = samples[n] * window_[static_cast<std::size_t>(n)];
    // The tail beyond frame_length stays zero from construction.
    fftw_execute_dft_r2c(plan_->plan, plan_->input,
                         plan_->output + static_cast<std::ptrdiff_t>(c) * stride_);
    if (corrections_.empty()) continue;
    auto* bins = reinterpret_cast<std::complex<double>*>(plan_->output +
                                                         static_cast<std::ptrdiff_t>(c) * stride_);
    const std::complex<double>* correction =
        corrections_.data() + static_cast<std::ptrdiff_t>(c) * bin_count();
    for (int k = 0; k < bin_count(); ++k) bins[k] *= correction[k];
  }
}

void MultichannelFft::set_channel_corrections(const std::vector<double>& delay_samples,
                                              const std::vector<double>& gain_db) {
  corrections_.clear();
  if (delay_samples.empty() && gain_db.empty()) return;
  corrections_.resize(static_cast<std::size_t>(channels_) * static_cast<std::size_t>(bin_count()));
  for (int c = 0; c < channels_; ++c) {
    const auto index = static_cast<std::size_t>(c);
    const double delay = index < delay_samples.size() ? delay_samples[index] : 0.0;
    const double scale = index < gain_db.size() ? std::pow(10.0, -gain_db[index] / 20.0) : 1.0;
    for (int k = 0; k < bin_count(); ++k)
      corrections_[index * static_cast<std::size_t>(bin_count()) + static_cast<std::size_t>(k)] =
          std::polar(scale, 2.0 * std::numbers::pi * k * delay / fft_size_);
  }
}

double MultichannelFft::overlap_variance_factor(int hop) const {
  if (hop <= 0) return 1.0;
  double factor = 1.0;
  for (int shift = hop; shift < frame_length_; shift += hop) {
    double overlap = 0.0;
    for (int n = 0; n + shift < frame_length_; ++n) {
      overlap +=
          window_[static_cast<std::size_t>(n)] * window_[static_cast<std::size_t>(n + shift)];
    }
    overlap /= window_energy_;
    factor += 2.0 * overlap * overlap;
  }
  return factor;
}

const std::complex<double>* MultichannelFft::spectrum(int channel) const {
  // fftw_complex is layout-compatible with std::complex<double> (FFTW manual 4.1.1).
  return reinterpret_cast<const std::complex<double>*>(
      plan_->output + static_cast<std::ptrdiff_t>(channel) * stride_);
}

}  // namespace dronetrack::doa
