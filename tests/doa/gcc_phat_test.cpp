// GCC-PHAT on exactly delayed band noise: TDOA bias at integer lags, half lags and the maximum
// lag, for the band-limited (Newton) refinement and, for comparison, parabolic interpolation.
#include "doa/gcc_phat.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <cstdio>
#include <initializer_list>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "doa/simd/dispatch.hpp"
#include "doa/spectral_frame.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa::gcc_phat_test {
namespace {

constexpr double kRate = 48000.0;
constexpr int kFrame = 8160;  // 0.17 s

// Whitens the frame of `recording` starting at sample `start` into each of `gccs` (one FFT).
void whiten_frame(const testing::Recording& recording, std::size_t start, MultichannelFft& fft,
                  std::initializer_list<GccPhat*> gccs) {
  Framer framer(fft.channels(), kFrame, kFrame);
  bool done = false;
  framer.push(recording.view(start, kFrame), [&](const FrameView& frame) {
    fft.process(frame);
    for (GccPhat* gcc : gccs) gcc->whiten(fft);
    done = true;
  });
  ASSERT_TRUE(done);
}

struct Estimate {
  double lag_s;
  double peak_value;
  double second_value;
};

// TDOA estimate of mic 0 delayed by `delay_s` relative to mic 1, on one frame.
Estimate estimate_delay(double delay_s, LagInterpolation interpolation, unsigned seed,
                        double noise_rms = 0.0, double max_lag_s = 0.5 / 343.0,
                        int oversample = 2) {
  const int length = 3 * 8192;
  const testing::BandNoise source(length, kRate, 1500.0, 3500.0, seed);
  testing::Recording recording = testing::silent_recording(2, length);
  recording.add(0, source.delayed(delay_s, 0.1));
  recording.add(1, source.delayed(0.0, 0.1));
  if (noise_rms > 0.0) testing::add_sensor_noise(recording, kRate, 1000.0, 4000.0, noise_rms, seed);
  Framer framer(2, kFrame, kFrame);
  MultichannelFft fft(2, kFrame, fftw_friendly_size(kFrame));
  GccPhat gcc(fft.fft_size(), kFrame, kRate, {FrequencyBand{}}, {{0, 1, max_lag_s}}, interpolation,
              oversample);
  Estimate estimate{0.0, 0.0, 0.0};
  bool done = false;
  framer.push(recording.view(4000, kFrame), [&](const FrameView& frame) {
    fft.process(frame);
    gcc.process(fft);
    estimate = {gcc.pair(0).peak.lag_s, gcc.pair(0).peak.value, gcc.pair(0).second_value};
    done = true;
  });
  EXPECT_TRUE(done);
  return estimate;
}

struct BiasFigures {
  double mean_abs_bias_samples;
  double max_abs_bias_samples;
};

BiasFigures bias_over_fractions(LagInterpolation interpolation, int oversample) {
  double sum = 0.0;
  double worst = 0.0;
  int count = 0;
  for (int whole = -3; whole <= 3; whole += 3) {
    for (int step = 0; step < 10; ++step) {
      const double delay_samples = whole + step / 10.0;
      double mean = 0.0;
      constexpr int kSeeds = 3;
      for (unsigned seed = 1; seed <= kSeeds; ++seed)
        mean +=
            estimate_delay(delay_samples / kRate, interpolation, seed, 0.0, 0.5 / 343.0, oversample)
                .lag_s *
            kRate;
      const double bias = mean / kSeeds - delay_samples;
      sum += std::abs(bias);
      worst = std::max(worst, std::abs(bias));
      ++count;
    }
  }
  return {sum / count, worst};
}

TEST(GccPhat, BandLimitedRefinementHasNegligibleBiasParabolicDoesNot) {
  // Same lag grid (2 samples at 48 kHz: the default, short inverse FFT) for both; parabolic also
  // on the full-rate grid (an inverse FFT 4x longer).
  const BiasFigures exact = bias_over_fractions(LagInterpolation::band_limited, 2);
  const BiasFigures parabolic = bias_over_fractions(LagInterpolation::parabolic, 2);
  const BiasFigures parabolic_full = bias_over_fractions(LagInterpolation::parabolic, 4);
  std::printf(
      "TDOA bias (samples at 48 kHz, noiseless, 0.17 s frame, 1.5-3.5 kHz):\n"
      "  band-limited Newton, 2-sample grid: mean |bias| %.5f, max %.5f\n"
      "  parabolic, 2-sample grid:           mean |bias| %.5f, max %.5f\n"
      "  parabolic, 1-sample grid:           mean |bias| %.5f, max %.5f\n",
      exact.mean_abs_bias_samples, exact.max_abs_bias_samples, parabolic.mean_abs_bias_samples,
      parabolic.max_abs_bias_samples, parabolic_full.mean_abs_bias_samples,
      parabolic_full.max_abs_bias_samples);
  EXPECT_LT(exact.max_abs_bias_samples, 0.002);
  EXPECT_GT(parabolic.max_abs_bias_samples, 5.0 * exact.max_abs_bias_samples);
}

class DelayEdges : public ::testing::TestWithParam<double> {};

TEST_P(DelayEdges, IntegerHalfAndMaximumLags) {
  const double max_lag_s = 0.5 / 343.0;  // 69.97 samples
  const double delay_s = GetParam() / kRate;
  const Estimate estimate =
      estimate_delay(delay_s, LagInterpolation::band_limited, 11, 0.0, max_lag_s);
  EXPECT_NEAR(estimate.lag_s * kRate, GetParam(), 0.01);
  EXPECT_GT(estimate.peak_value, 0.95);
  EXPECT_LT(estimate.second_value, 0.6 * estimate.peak_value);
}
INSTANTIATE_TEST_SUITE_P(Lags, DelayEdges,
                         ::testing::Values(0.0, 1.0, -7.0, 0.5, -12.5, 33.25, 69.9, -69.9));

TEST(GccPhat, NoisyDelayStaysWithinItsPredictedSpread) {
  // 0 dB in-band sensor noise: the spread of the estimates must be covered by the variance the
  // correlator reports (the input of the DOA covariance).
  double sum_squares = 0.0;
  double predicted = 0.0;
  constexpr int kTrials = 40;
  const double delay_s = 20.3 / kRate;
  for (unsigned seed = 1; seed <= kTrials; ++seed) {
    const int length = 3 * 8192;
    const testing::BandNoise source(length, kRate, 1500.0, 3500.0, seed);
    testing::Recording recording = testing::silent_recording(2, length);
    recording.add(0, source.delayed(delay_s, 0.1));
    recording.add(1, source.delayed(0.0, 0.1));
    testing::add_sensor_noise(recording, kRate, 1500.0, 3500.0, 0.1, 1000 + seed);
    Framer framer(2, kFrame, kFrame);
    MultichannelFft fft(2, kFrame, fftw_friendly_size(kFrame));
    GccPhat gcc(fft.fft_size(), kFrame, kRate, {FrequencyBand{}}, {{0, 1, 0.5 / 343.0}});
    framer.push(recording.view(0, kFrame), [&](const FrameView& frame) {
      fft.process(frame);
      gcc.process(fft);
    });
    const double error = gcc.pair(0).peak.lag_s - delay_s;
    sum_squares += error * error;
    predicted += gcc.pair(0).tdoa_variance_s2;
  }
  const double ratio = sum_squares / predicted;  // ~1 when the variance is honest
  std::printf("noisy TDOA: rms error %.3f us, predicted %.3f us\n",
              1e6 * std::sqrt(sum_squares / kTrials), 1e6 * std::sqrt(predicted / kTrials));
  EXPECT_GT(ratio, 0.3);
  EXPECT_LT(ratio, 2.5);
}

// The lag grid is the continuous correlation at the grid lags, however it is computed: by the
// inverse FFT or by direct sums over the kept bins (few kept, as after a loud source's bins are
// dropped; with eight or more float lanes the whole band too), both in single precision, so to
// ~1e-7 of a peak's 1. A refined peak asked for again is the same peak.
TEST(GccPhat, LagGridMatchesContinuousCorrelationWithAllOrFewBinsKept) {
  const int length = 2 * 8192;
  const testing::BandNoise first(length, kRate, 1500.0, 3500.0, 11);
  const testing::BandNoise second(length, kRate, 1500.0, 3500.0, 12);
  testing::Recording recording = testing::silent_recording(3, length);
  recording.add(0, first.delayed(3.3 / kRate, 0.1));
  recording.add(1, first.delayed(0.0, 0.1));
  recording.add(2, first.delayed(-5.7 / kRate, 0.1));
  recording.add(0, second.delayed(-2.0 / kRate, 0.05));
  recording.add(2, second.delayed(1.5 / kRate, 0.05));
  testing::add_sensor_noise(recording, kRate, 1000.0, 4000.0, 0.01, 13);
  MultichannelFft fft(3, kFrame, fftw_friendly_size(kFrame));
  const double max_lag_s = 0.8 / 343.0;
  GccPhat gcc(fft.fft_size(), kFrame, kRate, {FrequencyBand{}},
              {{0, 1, max_lag_s}, {0, 2, max_lag_s}, {1, 2, max_lag_s}});
  ASSERT_NO_FATAL_FAILURE(whiten_frame(recording, 2000, fft, {&gcc}));
  auto check_grid = [&](const char* what, double tolerance) {
    for (int p = 0; p < gcc.pair_count(); ++p) {
      const std::span<const double> values = gcc.grid(p);
      const int half = gcc.half_span(p);
      for (int m = -half; m <= half; ++m)
        EXPECT_NEAR(values[static_cast<std::size_t>(m + half)],
                    gcc.value_at(p, m * gcc.lag_step_s()), tolerance)
            << what << " pair " << p << " lag index " << m;
    }
  };
  const std::vector<std::uint8_t> whitened_mask(gcc.bin_keep().begin(), gcc.bin_keep().end());
  gcc.correlate();  // every bin: inverse FFT or direct sums, per the target
  check_grid("all bins kept", 1e-6);
  for (int p = 0; p < gcc.pair_count(); ++p) {
    GccPeak again;
    ASSERT_TRUE(gcc.refine(p, gcc.pair(p).peak.lag_s, again));
    EXPECT_EQ(again.lag_s, gcc.pair(p).peak.lag_s);
    EXPECT_EQ(again.value, gcc.pair(p).peak.value);
  }
  // Every seventh bin kept (14 %): direct sums.
  const std::span<std::uint8_t> keep = gcc.bin_keep();
  for (std::size_t k = 0; k < keep.size(); ++k) keep[k] = k % 7 == 0 ? 1 : 0;
  gcc.correlate(false);
  EXPECT_LT(gcc.kept_bin_count(), gcc.band_bin_count() / 5);
  check_grid("few bins kept", 1e-6);
  // Back to the whitening's cross-power: the same grid and peaks as the first time.
  gcc.cross_power(gcc.units(), whitened_mask);
  gcc.correlate();
  EXPECT_EQ(gcc.kept_bin_count(), gcc.band_bin_count());
  check_grid("restored", 1e-6);
}

// A wide band on a long baseline (0.5-6 kHz, 2 m: 939 bins x 141 lags, 2.7 products per point
// of the 4096-point inverse FFT) takes the FFT on every target, and the same pair with every
// 20th bin kept (0.13) the direct sums: both give the continuous correlation at the grid lags,
// and the peak is the source's delay.
TEST(GccPhat, FftAndDirectSumsBothGiveTheCorrelationOnAWideBandAndLongBaseline) {
  const int length = 2 * 8192;
  const double delay_samples = 100.3;
  const testing::BandNoise source(length, kRate, 500.0, 6000.0, 41);
  testing::Recording recording = testing::silent_recording(2, length);
  recording.add(0, source.delayed(delay_samples / kRate, 0.1));
  recording.add(1, source.delayed(0.0, 0.1));
  testing::add_sensor_noise(recording, kRate, 100.0, 12000.0, 0.01, 42);
  MultichannelFft fft(2, kFrame, fftw_friendly_size(kFrame));
  GccPhat gcc(fft.fft_size(), kFrame, kRate, {FrequencyBand{500.0, 6000.0}}, {{0, 1, 2.0 / 343.0}});
  ASSERT_NO_FATAL_FAILURE(whiten_frame(recording, 2000, fft, {&gcc}));
  ASSERT_GT(gcc.half_span(0), 130);
  const auto check_grid = [&](const char* what) {
    const std::span<const double> values = gcc.grid(0);
    const int half = gcc.half_span(0);
    for (int m = -half; m <= half; ++m)
      EXPECT_NEAR(values[static_cast<std::size_t>(m + half)], gcc.value_at(0, m * gcc.lag_step_s()),
                  1e-6)
          << what << " lag index " << m;
  };
  gcc.correlate();
  check_grid("whole band (inverse FFT)");
  EXPECT_NEAR(gcc.pair(0).peak.lag_s, delay_samples / kRate, 0.1 / kRate);
  const std::span<std::uint8_t> keep = gcc.bin_keep();
  for (std::size_t k = 0; k < keep.size(); ++k) keep[k] = k % 20 == 0 ? 1 : 0;
  gcc.correlate(true, false);
  check_grid("every 20th bin (direct sums)");
  EXPECT_NEAR(gcc.pair(0).peak.lag_s, delay_samples / kRate, 0.5 / kRate);
}

// Two band-noise sources on four mics, each exactly delayed per mic, and sensor noise (seeds
// `seed` to `seed` + 2): two frames' worth.
testing::Recording two_sources_on_four_mics(unsigned seed) {
  const int length = 2 * 8192;
  const testing::BandNoise first(length, kRate, 1500.0, 3500.0, seed);
  const testing::BandNoise second(length, kRate, 1500.0, 3500.0, seed + 1);
  testing::Recording recording = testing::silent_recording(4, length);
  recording.add(0, first.delayed(3.3 / kRate, 0.1));
  recording.add(1, first.delayed(0.0, 0.1));
  recording.add(2, first.delayed(-5.7 / kRate, 0.1));
  recording.add(3, first.delayed(9.1 / kRate, 0.1));
  recording.add(0, second.delayed(-2.0 / kRate, 0.05));
  recording.add(3, second.delayed(1.5 / kRate, 0.05));
  testing::add_sensor_noise(recording, kRate, 1000.0, 4000.0, 0.01, seed + 2);
  return recording;
}

// Every pair of four mics at most 0.8 m apart.
std::vector<MicPairSpec> four_mic_pairs() {
  const double max_lag_s = 0.8 / 343.0;
  std::vector<MicPairSpec> pairs;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) pairs.push_back({i, j, max_lag_s});
  return pairs;
}

// Every SIMD target this CPU has (Highway's dispatch forced to each in turn: AVX-512, AVX2,
// SSE4 on x86-64; NEON on arm64) gives the same grid, peaks and coherence on one frame of two
// sources, with every bin kept (the FFT or, with wide vectors, direct sums) and with few kept
// (direct sums everywhere); and the calls land on the target forced (counts).
TEST(GccPhat, EverySimdTargetAgrees) {
  const testing::Recording recording = two_sources_on_four_mics(21);
  MultichannelFft fft(4, kFrame, fftw_friendly_size(kFrame));
  const std::vector<MicPairSpec> pairs = four_mic_pairs();
  struct Look {
    std::vector<std::vector<double>> grids;
    std::vector<PairCorrelation> pairs;
  };
  struct Outcome {
    std::string target;
    Look all_kept;
    Look few_kept;
  };
  const auto look = [](const GccPhat& gcc) {
    Look out;
    for (int p = 0; p < gcc.pair_count(); ++p) {
      out.grids.emplace_back(gcc.grid(p).begin(), gcc.grid(p).end());
      out.pairs.push_back(gcc.pair(p));
    }
    return out;
  };
  std::vector<Outcome> outcomes;
  for (const char* target : {"AVX3", "AVX2", "SSE4", "NEON", "SCALAR"}) {
    try {
      set_simd_target(target);
    } catch (const std::invalid_argument&) {
      continue;  // not on this CPU
    }
    ASSERT_EQ(simd_target_name(), target);
    const std::uint64_t calls_before = simd_dispatch_count(target);
    GccPhat gcc(fft.fft_size(), kFrame, kRate, {FrequencyBand{}}, pairs);
    ASSERT_NO_FATAL_FAILURE(whiten_frame(recording, 2000, fft, {&gcc}));
    const std::vector<std::uint8_t> whitened_mask(gcc.bin_keep().begin(), gcc.bin_keep().end());
    gcc.correlate();
    Outcome outcome{target, look(gcc), {}};
    gcc.cross_power(gcc.units(), whitened_mask);
    const std::span<std::uint8_t> keep = gcc.bin_keep();
    for (std::size_t k = 0; k < keep.size(); ++k) keep[k] = k % 5 == 0 ? 1 : 0;
    gcc.correlate(true, false);  // 20 % kept: direct sums on every target
    outcome.few_kept = look(gcc);
    outcomes.push_back(outcome);
    EXPECT_GT(simd_dispatch_count(target), calls_before) << target;
  }
  set_simd_target("auto");
  ASSERT_FALSE(outcomes.empty());
  const Outcome& reference = outcomes.front();
  auto compare = [&](const Outcome& other, const Look& a, const Look& b, const char* what,
                     double grid_tolerance) {
    for (std::size_t p = 0; p < a.pairs.size(); ++p) {
      ASSERT_EQ(a.grids[p].size(), b.grids[p].size());
      for (std::size_t m = 0; m < a.grids[p].size(); ++m)
        EXPECT_NEAR(a.grids[p][m], b.grids[p][m], grid_tolerance)
            << other.target << " " << what << " pair " << p << " lag " << m;
      EXPECT_NEAR(a.pairs[p].peak.lag_s, b.pairs[p].peak.lag_s, 1e-12) << other.target << what;
      EXPECT_NEAR(a.pairs[p].peak.value, b.pairs[p].peak.value, 1e-12) << other.target << what;
      EXPECT_NEAR(a.pairs[p].coherence, b.pairs[p].coherence, 1e-12) << other.target << what;
      EXPECT_GT(b.pairs[p].peak.value, 0.1) << other.target << what;  // a real peak
    }
  };
  for (const Outcome& other : outcomes) {
    compare(other, reference.all_kept, other.all_kept, "all bins kept", 1e-6);
    compare(other, reference.few_kept, other.few_kept, "every 5th bin kept", 1e-6);
  }
}

// The grid-less re-measure (refine_from) finds the peak correlate() + refine()
// find, from a start a fraction of a grid step off, and gives up beyond its reach.
// A stage that rewrites a few bins' spectra in place (StaticSourceCancel) remakes only those
// bins' pair products (remake_bins): the correlation afterwards is, to the last bit, the one a
// cross_power() of the whole band under the same mask gives. Bins dropped, some of them
// rewritten and kept again (scattered and a run, so runs start and end inside vectors), SNR
// weights on, as in the node.
TEST(GccPhat, RemadeBinsGiveWhatTheWholeCrossPowerGives) {
  const testing::Recording recording = two_sources_on_four_mics(31);
  MultichannelFft fft(4, kFrame, fftw_friendly_size(kFrame));
  const std::vector<MicPairSpec> pairs = four_mic_pairs();
  // Weighted (the node's first look) and plain (the products' single-precision copy is read
  // as remade: a weighted look writes it again).
  for (const bool weighted : {true, false}) {
    GccPhat remade(fft.fft_size(), kFrame, kRate, {FrequencyBand{}}, pairs);
    GccPhat whole(fft.fft_size(), kFrame, kRate, {FrequencyBand{}}, pairs);
    ASSERT_NO_FATAL_FAILURE(whiten_frame(recording, 2000, fft, {&remade, &whole}));
    const int bins = remade.band_bin_count();
    ASSERT_GT(bins, 260);
    std::vector<std::uint8_t> changed(static_cast<std::size_t>(bins), 0);
    std::vector<std::complex<double>> spectrum(4);
    for (GccPhat* gcc : {&remade, &whole}) {
      for (int k = 0; k < bins; ++k)
        gcc->bin_weight()[static_cast<std::size_t>(k)] = 0.3 + 0.7 * std::fmod(0.37 * k, 1.0);
      const std::span<std::uint8_t> keep = gcc->bin_keep();
      for (int k = 0; k < bins; ++k) {
        const bool dropped = (k >= 20 && k < 120 && k % 3 != 0) || (k >= 201 && k < 243);
        if (!dropped) continue;
        keep[static_cast<std::size_t>(k)] = 0;
        if (k % 5 == 0) continue;  // dropped and left dropped
        // Rewritten as a projection would: each mic's bin turned and scaled its own way.
        for (int m = 0; m < 4; ++m) {
          const auto at = static_cast<std::size_t>(m * bins + k);
          spectrum[static_cast<std::size_t>(m)] =
              std::polar(0.4 * gcc->band_levels()[at], 0.3 * (m + 1)) *
              std::complex<double>(gcc->units().real[at], gcc->units().imag[at]);
        }
        gcc->set_bin_spectrum(k, spectrum);
        keep[static_cast<std::size_t>(k)] = 1;
        changed[static_cast<std::size_t>(k)] = 1;
      }
    }
    remade.remake_bins(changed);
    whole.cross_power(whole.units(), whole.bin_keep());
    remade.correlate(true, weighted);
    whole.correlate(true, weighted);
    for (int p = 0; p < remade.pair_count(); ++p) {
      const std::span<const double> grid = remade.grid(p);
      const std::span<const double> expected = whole.grid(p);
      for (std::size_t n = 0; n < grid.size(); ++n)
        ASSERT_EQ(grid[n], expected[n]) << "weighted " << weighted << " pair " << p << " lag " << n;
      EXPECT_EQ(remade.pair(p).peak.lag_s, whole.pair(p).peak.lag_s);
      EXPECT_EQ(remade.pair(p).peak.value, whole.pair(p).peak.value);
      EXPECT_EQ(remade.pair(p).coherence, whole.pair(p).coherence);
      EXPECT_EQ(remade.pair(p).tdoa_variance_s2, whole.pair(p).tdoa_variance_s2);
    }
    // After a correlation the phasors carry the mask and weights: a partial remake would mix.
    EXPECT_THROW(remade.remake_bins(changed), std::logic_error);
    std::fill(changed.begin(), changed.end(), std::uint8_t{0});
  }
}

TEST(GccPhat, RefineFromKnownLagMatchesTheGridRefinement) {
  const int length = 2 * 8192;
  const testing::BandNoise source(length, kRate, 1500.0, 3500.0, 31);
  testing::Recording recording = testing::silent_recording(2, length);
  recording.add(0, source.delayed(4.37 / kRate, 0.1));
  recording.add(1, source.delayed(0.0, 0.1));
  testing::add_sensor_noise(recording, kRate, 1000.0, 4000.0, 0.02, 32);
  MultichannelFft fft(2, kFrame, fftw_friendly_size(kFrame));
  GccPhat gcc(fft.fft_size(), kFrame, kRate, {FrequencyBand{}}, {{0, 1, 0.8 / 343.0}});
  ASSERT_NO_FATAL_FAILURE(whiten_frame(recording, 0, fft, {&gcc}));
  gcc.correlate();
  const GccPeak with_grid = gcc.pair(0).peak;
  EXPECT_NEAR(with_grid.lag_s, 4.37 / kRate, 0.2 / kRate);  // sensor noise at 14 dB
  gcc.cross_power(gcc.units(), std::vector<std::uint8_t>(gcc.bin_keep().size(), 1), true);
  for (const double offset_steps : {-0.4, 0.0, 0.3}) {
    GccPeak from_lag;
    ASSERT_TRUE(gcc.refine_from(0, with_grid.lag_s + offset_steps * gcc.lag_step_s(), from_lag));
    EXPECT_NEAR(from_lag.lag_s, with_grid.lag_s, 1e-9) << offset_steps;
    EXPECT_NEAR(from_lag.value, with_grid.value, 1e-9) << offset_steps;
  }
  // Farther than its reach (1.5 grid steps) from the start, no answer rather than a far peak.
  GccPeak far_start;
  EXPECT_FALSE(gcc.refine_from(0, with_grid.lag_s + 3.0 * gcc.lag_step_s(), far_start));
}

TEST(BandRuns, MergesBandsAndRejectsEmpty) {
  const std::vector<BandRun> runs =
      band_runs({{1000, 2000}, {1900, 3000}, {5000, 6000}}, 48000.0, 4800);
  ASSERT_EQ(runs.size(), 2U);
  EXPECT_EQ(runs[0].first_bin, 100);
  EXPECT_EQ(runs[0].last_bin, 300);
  EXPECT_EQ(runs[1].first_bin, 500);
  EXPECT_THROW(band_runs({{30000, 40000}}, 48000.0, 4800), std::invalid_argument);
}

TEST(FftwFriendlySize, PowerOfTwoOrSmooth) {
  EXPECT_EQ(fftw_friendly_size(8160), 8192);
  EXPECT_EQ(fftw_friendly_size(9600), 9600);  // 0.2 s at 48 kHz: 2^7 3 5^2
  const int size = fftw_friendly_size(8193);
  int rest = size;
  for (const int factor : {2, 3, 5})
    while (rest % factor == 0) rest /= factor;
  EXPECT_EQ(rest, 1);
  EXPECT_GE(size, 8193);
  EXPECT_LT(size, 9216);
}

TEST(MultichannelFft, OverlapVarianceFactorOfHannFrames) {
  // Hann, w = sin^2: half a frame later the overlap is sum sin^2 cos^2 over half the frame,
  // N/16, against sum sin^4 = 3N/8, so c = 1/6 and the factor 1 + 2/36.
  const MultichannelFft fft(1, 8192, 8192);
  EXPECT_NEAR(fft.overlap_variance_factor(4096), 1.0 + 2.0 / 36.0, 1e-3);
  EXPECT_DOUBLE_EQ(fft.overlap_variance_factor(8192), 1.0);  // no overlap
  EXPECT_DOUBLE_EQ(fft.overlap_variance_factor(0), 1.0);
  // The defaults (0.17 s frames every 0.05 s): a third of the noise shared with each neighbour.
  const double factor = fft.overlap_variance_factor(2400);
  std::printf("Hann overlap variance factor, 8192-sample frames every 2400: %.3f\n", factor);
  EXPECT_GT(factor, 1.5);
  EXPECT_LT(factor, 1.8);
  EXPECT_GT(fft.overlap_variance_factor(1200), factor);  // denser frames share more
}

}  // namespace
}  // namespace dronetrack::doa::gcc_phat_test
