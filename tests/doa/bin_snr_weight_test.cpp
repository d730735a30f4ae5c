// Per-bin SNR weights against known answers: noise-only bins fade, a source's bins stand out, odd
// spectra fall back on plain PHAT; and the weights' purpose, a better TDOA at low SNR when the
// source's power sits in part of the band.
#include "doa/bin_snr_weight.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "doa/gcc_phat.hpp"
#include "doa/spectral_frame.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa::bin_snr_weight_test {
namespace {

constexpr double kRate = 48000.0;
constexpr int kFrame = 8160;  // 0.17 s
constexpr int kHop = 2400;    // 0.05 s
constexpr double kHopSeconds = kHop / kRate;

// Two mics; white sensor noise throughout; from `source_start_s` a source made of `lines` narrow
// bands (a rotor's harmonics: `line_width_hz` wide, every `spacing_hz` from `first_hz`), mic 0
// lagging mic 1 by `delay_s`; each line at RMS `line_rms`.
struct SourceLines {
  double first_hz = 2000.0;
  double spacing_hz = 160.0;
  int lines = 1;
  double line_width_hz = 400.0;
  double line_rms = 0.1;
};
testing::Recording two_mic_scene(double seconds, double source_start_s, const SourceLines& source,
                                 double delay_s, unsigned seed) {
  const auto length = static_cast<int>(seconds * kRate);
  testing::Recording recording = testing::silent_recording(2, static_cast<std::size_t>(length));
  const auto start = static_cast<std::size_t>(source_start_s * kRate);
  for (int line = 0; line < source.lines; ++line) {
    const double low_hz = source.first_hz + line * source.spacing_hz;
    const testing::BandNoise tone(length, kRate, low_hz, low_hz + source.line_width_hz,
                                  seed + 31U * static_cast<unsigned>(line));
    std::vector<double> late = tone.delayed(delay_s, source.line_rms);
    std::vector<double> early = tone.delayed(0.0, source.line_rms);
    for (std::size_t n = 0; n < start && n < late.size(); ++n) late[n] = early[n] = 0.0;
    recording.add(0, late);
    recording.add(1, early);
  }
  testing::add_sensor_noise(recording, kRate, 500.0, 6000.0, 0.05, seed + 1);
  return recording;
}

struct FrameLoop {
  Framer framer{2, kFrame, kHop};
  MultichannelFft fft{2, kFrame, fftw_friendly_size(kFrame)};
  GccPhat gcc{fft.fft_size(), kFrame, kRate, {FrequencyBand{}}, {{0, 1, 0.5 / 343.0}}};
  BinSnrWeight weights{gcc.band(), kHopSeconds, 1.0, 0.0};
};

// Mean weight of the band bins inside / outside [low_hz, high_hz] at the last frame.
void mean_weights(const GccPhat& gcc, std::span<const double> weights, double low_hz,
                  double high_hz, int fft_size, double& inside, double& outside) {
  double sum_in = 0.0, sum_out = 0.0;
  int count_in = 0, count_out = 0;
  std::size_t index = 0;
  for (const BandRun& run : gcc.band()) {
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      const double frequency = k * kRate / fft_size;
      if (frequency >= low_hz && frequency <= high_hz) {
        sum_in += weights[index];
        ++count_in;
      } else {
        sum_out += weights[index];
        ++count_out;
      }
    }
  }
  inside = count_in > 0 ? sum_in / count_in : 0.0;
  outside = count_out > 0 ? sum_out / count_out : 0.0;
}

TEST(BinSnrWeight, NoiseFadesAndAnArrivingSourceStandsOut) {
  // 2 s of noise, then a source in 2.0-2.4 kHz, ~20 dB above the noise in its bins.
  const testing::Recording recording = two_mic_scene(3.0, 2.0, SourceLines{}, 0.0, 3);
  FrameLoop loop;
  std::vector<double> weights(static_cast<std::size_t>(loop.gcc.band_bin_count()), 1.0);
  double noise_only_mean = -1.0, source_in = -1.0, source_out = -1.0;
  int frames = 0;
  loop.framer.push(recording.view(0, recording.frames()), [&](const FrameView& frame) {
    loop.fft.process(frame);
    loop.gcc.whiten(loop.fft);
    loop.weights.update(loop.gcc.band_powers(), loop.gcc.unit_channels(), weights);
    ++frames;
    const double end_s = (static_cast<double>(frame.first_sample) + frame.length) / kRate;
    double in = 0.0, out = 0.0;
    mean_weights(loop.gcc, weights, 2050.0, 2350.0, loop.fft.fft_size(), in, out);
    if (end_s < 1.95) noise_only_mean = 0.5 * (in + out);
    if (end_s > 2.6) {
      source_in = in;
      source_out = out;
    }
  });
  ASSERT_GT(frames, 40);
  // Pure noise: a bin rises above its tracked floor only by chance, and not by much.
  EXPECT_LT(noise_only_mean, 0.2);
  EXPECT_GT(source_in, 0.85);
  EXPECT_LT(source_out, 0.2);
}

TEST(BinSnrWeight, FloorAndNonFiniteSpectraKeepPlainPhat) {
  const testing::Recording recording =
      two_mic_scene(1.0, 0.0, SourceLines{2000.0, 160.0, 1, 400.0, 0.0}, 0.0, 5);
  FrameLoop loop;
  BinSnrWeight floored(loop.gcc.band(), kHopSeconds, 1.0, 0.3);
  std::vector<double> weights(static_cast<std::size_t>(loop.gcc.band_bin_count()), 0.0);
  loop.framer.push(recording.view(0, recording.frames()), [&](const FrameView& frame) {
    loop.fft.process(frame);
    loop.gcc.whiten(loop.fft);
    floored.update(loop.gcc.band_powers(), loop.gcc.unit_channels(), weights);
    for (const double w : weights) {
      EXPECT_GE(w, 0.3);
      EXPECT_LE(w, 1.0);
    }
  });
  // A NaN that reaches the spectra (the framer zeroes them; a caller may not): every bin gets
  // weight 1, plain PHAT, and the estimates are left alone.
  std::vector<double> channels(2 * static_cast<std::size_t>(kFrame), 0.01);
  channels[1000] = std::numeric_limits<double>::quiet_NaN();
  loop.fft.process(FrameView{0, 2, kFrame, channels.data(), 0, 0});
  loop.gcc.whiten(loop.fft);
  std::fill(weights.begin(), weights.end(), 0.5);
  floored.update(loop.gcc.band_powers(), loop.gcc.unit_channels(), weights);
  for (const double w : weights) EXPECT_EQ(w, 1.0);
  // After the bad frame, clean frames give floored weights again.
  loop.framer.reset();
  loop.framer.push(recording.view(0, recording.frames()), [&](const FrameView& frame) {
    loop.fft.process(frame);
    loop.gcc.whiten(loop.fft);
    floored.update(loop.gcc.band_powers(), loop.gcc.unit_channels(), weights);
    for (const double w : weights) EXPECT_TRUE(std::isfinite(w) && w >= 0.3 && w <= 1.0);
  });
}

// The point of the weights: a rotor-like source, its power in narrow harmonics that cover ~15 %
// of the band, below the noise over the band as a whole, is timed better when the noise-only
// bins fade.
TEST(BinSnrWeight, WeightedCorrelationTimesAHarmonicSourceBetter) {
  const SourceLines kRotor{1610.0, 160.0, 12, 24.0, 0.009};
  const double delay_s = 0.37e-3;
  const testing::Recording recording = two_mic_scene(6.0, 1.0, kRotor, delay_s, 11);
  FrameLoop loop;
  // The default weight floor keeps a share of every bin (a steady source is learned as noise by
  // the minimum tracking): less gain, still a clear one.
  BinSnrWeight floored(loop.gcc.band(), kHopSeconds, 1.0, DoaParams{}.snr_weight_floor);
  std::vector<double> floored_weights(static_cast<std::size_t>(loop.gcc.band_bin_count()), 1.0);
  double sum2[3] = {0.0, 0.0, 0.0};  // plain, weighted, weighted with the default floor
  int counted = 0;
  loop.framer.push(recording.view(0, recording.frames()), [&](const FrameView& frame) {
    loop.fft.process(frame);
    loop.gcc.whiten(loop.fft);
    floored.update(loop.gcc.band_powers(), loop.gcc.unit_channels(), floored_weights);
    loop.weights.update(loop.gcc.band_powers(), loop.gcc.unit_channels(), loop.gcc.bin_weight());
    if (static_cast<double>(frame.first_sample) / kRate < 1.5) return;  // source on, noise known
    loop.gcc.correlate(true, false);
    const double plain = loop.gcc.pair(0).peak.lag_s - delay_s;
    loop.gcc.correlate(true, true);
    const double weighted = loop.gcc.pair(0).peak.lag_s - delay_s;
    // Weights change only on plain phasors: the next frame's update() follows a whiten().
    loop.gcc.correlate(true, false);
    std::vector<double> wiener(loop.gcc.bin_weight().begin(), loop.gcc.bin_weight().end());
    std::copy(floored_weights.begin(), floored_weights.end(), loop.gcc.bin_weight().begin());
    loop.gcc.correlate(true, true);
    const double weighted_floor = loop.gcc.pair(0).peak.lag_s - delay_s;
    loop.gcc.correlate(true, false);
    std::copy(wiener.begin(), wiener.end(), loop.gcc.bin_weight().begin());
    sum2[0] += plain * plain;
    sum2[1] += weighted * weighted;
    sum2[2] += weighted_floor * weighted_floor;
    ++counted;
  });
  ASSERT_GT(counted, 50);
  const double plain_us = 1e6 * std::sqrt(sum2[0] / counted);
  const double weighted_us = 1e6 * std::sqrt(sum2[1] / counted);
  const double floor_us = 1e6 * std::sqrt(sum2[2] / counted);
  std::printf(
      "TDOA RMS error over %d frames: plain PHAT %.1f us, SNR-weighted %.1f us, with the "
      "default floor %.1f us\n",
      counted, plain_us, weighted_us, floor_us);
  EXPECT_LT(weighted_us, 20.0);
  EXPECT_LT(weighted_us, 0.1 * plain_us);
  EXPECT_LT(floor_us, 0.6 * plain_us);
}

}  // namespace
}  // namespace dronetrack::doa::bin_snr_weight_test
