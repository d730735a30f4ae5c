// The per-frame statistics' SIMD kernels (doa/simd/stats_kernels.cpp) and the framer's
// deinterleave on every target this CPU has, against plain scalar references: row lengths that
// leave partial vectors, ties, NaN.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "doa/simd/dispatch.hpp"
#include "doa/simd/kernels.hpp"

namespace dronetrack::doa::simd_kernels_test {
namespace {

// Runs `check` once per target available here (at least the best one), then restores dispatch.
template <class Check>
void on_every_target(Check check) {
  int targets = 0;
  for (const char* target : {"AVX3", "AVX2", "SSE4", "NEON", "SCALAR"}) {
    try {
      set_simd_target(target);
    } catch (const std::invalid_argument&) {
      continue;  // not on this CPU
    }
    const std::uint64_t calls_before = simd_dispatch_count(target);
    check(std::string(target));
    EXPECT_GT(simd_dispatch_count(target), calls_before) << target << ": kernel not dispatched";
    ++targets;
  }
  set_simd_target("auto");
  EXPECT_GE(targets, 1);
}

TEST(SimdKernels, SnrWeightsMatchTheScalarUpdate) {
  std::mt19937 random(7);
  std::exponential_distribution<double> power_of(1.0);
  for (const std::size_t count : {std::size_t{1}, std::size_t{7}, std::size_t{342}}) {
    std::vector<double> power(count), smoothed(count), noise(count);
    for (std::size_t k = 0; k < count; ++k) {
      power[k] = power_of(random);
      smoothed[k] = power_of(random);
      noise[k] = k % 3 == 0 ? 0.0 : 0.3 * power_of(random);  // 0: the tiny floor decides
    }
    constexpr double kSmoothing = 0.6, kRise = 1.01, kTiny = 1e-30, kBias = 2.0, kFloor = 0.05;
    std::vector<double> want_smoothed(count), want_noise(count), want_weight(count);
    for (std::size_t k = 0; k < count; ++k) {
      want_smoothed[k] = kSmoothing * smoothed[k] + (1.0 - kSmoothing) * power[k];
      want_noise[k] = std::max(std::min(want_smoothed[k], noise[k] * kRise), kTiny);
      const double snr = std::max(want_smoothed[k] / (kBias * want_noise[k]) - 1.0, 0.0);
      want_weight[k] = std::max(snr / (1.0 + snr), kFloor);
    }
    on_every_target([&](const std::string& target) {
      std::vector<double> got_smoothed = smoothed, got_noise = noise, weights(count + 1, -1.0);
      simd::snr_weights({power.data(), got_smoothed.data(), got_noise.data(), weights.data(), count,
                         kSmoothing, kRise, kTiny, kBias, kFloor});
      for (std::size_t k = 0; k < count; ++k) {
        EXPECT_NEAR(got_smoothed[k], want_smoothed[k], 1e-15 * want_smoothed[k]) << target << k;
        EXPECT_NEAR(got_noise[k], want_noise[k], 1e-15 * want_noise[k]) << target << k;
        EXPECT_NEAR(weights[k], want_weight[k], 1e-14) << target << k;
      }
      EXPECT_EQ(weights[count], -1.0) << target << ": wrote past the row";
    });
  }
}

TEST(SimdKernels, MiddleValueIsTheSortedMiddle) {
  std::mt19937 random(11);
  std::uniform_int_distribution<int> level(0, 5);  // few levels: many ties
  for (int count = 1; count <= 19; ++count) {
    std::vector<double> values(static_cast<std::size_t>(count));
    for (double& value : values) value = 0.5 * level(random) - 1.0;
    std::vector<double> sorted = values;
    std::sort(sorted.begin(), sorted.end());
    const double want = sorted[static_cast<std::size_t>(count / 2)];
    on_every_target([&](const std::string& target) {
      EXPECT_EQ(simd::middle_value(values.data(), count), want) << target << " count " << count;
    });
  }
}

TEST(SimdKernels, ChannelSumsPerChannel) {
  std::mt19937 random(13);
  std::uniform_real_distribution<float> sample(-1.0F, 1.0F);
  for (int channels = 1; channels <= simd::kMaxInterleavedChannels; ++channels) {
    for (const std::size_t frames : {std::size_t{3}, std::size_t{37}, std::size_t{4096}}) {
      std::vector<float> interleaved(frames * static_cast<std::size_t>(channels));
      for (float& value : interleaved) value = sample(random);
      // The last channel's largest sample, negative and late (in the scalar tail or not).
      interleaved[interleaved.size() - 1] = -1.5F;
      std::vector<double> want_sum(static_cast<std::size_t>(channels), 0.0);
      std::vector<double> want_square = want_sum, want_peak = want_sum;
      for (std::size_t n = 0; n < interleaved.size(); ++n) {
        const std::size_t c = n % static_cast<std::size_t>(channels);
        want_sum[c] += interleaved[n];
        want_square[c] += static_cast<double>(interleaved[n]) * interleaved[n];
        want_peak[c] = std::max(want_peak[c], std::fabs(static_cast<double>(interleaved[n])));
      }
      on_every_target([&](const std::string& target) {
        std::vector<float> sums(static_cast<std::size_t>(channels), -9.0F);
        std::vector<float> squares = sums, peaks = sums;
        simd::channel_sums(
            {interleaved.data(), frames, channels, sums.data(), squares.data(), peaks.data()});
        for (std::size_t c = 0; c < sums.size(); ++c) {
          // Float sums of `frames` values: ~frames x 6e-8 of the sum of magnitudes.
          const double tolerance = 1e-6 * static_cast<double>(frames);
          EXPECT_NEAR(sums[c], want_sum[c], tolerance) << target << channels << " ch " << c;
          EXPECT_NEAR(squares[c], want_square[c], tolerance) << target << channels << " ch " << c;
          EXPECT_EQ(peaks[c], want_peak[c]) << target << channels << " ch " << c;
        }
      });
    }
  }
  // A NaN sample makes its channel's squares NaN, and no other channel's.
  std::vector<float> interleaved(4 * 100, 0.25F);
  interleaved[4 * 50 + 2] = std::numeric_limits<float>::quiet_NaN();
  on_every_target([&](const std::string& target) {
    float sums[4], squares[4], peaks[4];
    simd::channel_sums({interleaved.data(), 100, 4, sums, squares, peaks});
    for (int c = 0; c < 4; ++c) EXPECT_EQ(std::isnan(squares[c]), c == 2) << target << c;
  });
}

// Four interleaved channels split into rows of doubles, with each channel's sum, squares and
// peak: whole vectors only (the rest is the caller's), every value copied exactly.
TEST(SimdKernels, DeinterleaveFourSplitsAndSumsPerChannel) {
  std::mt19937 random(17);
  std::uniform_real_distribution<float> sample(-1.0F, 1.0F);
  for (const int frames : {3, 37, 2400}) {
    std::vector<float> interleaved;
    for (int n = 0; n < 4 * frames; ++n)  // channel 3's peak, early: in every target's vectors
      interleaved.push_back(n == 4 * 2 + 3 ? -1.25F : sample(random));
    constexpr std::ptrdiff_t kStride = 2500;
    on_every_target([&](const std::string& target) {
      std::vector<double> rows(4 * kStride, -9.0);
      double sums[4] = {}, squares[4] = {}, peaks[4] = {};
      const int done = simd::deinterleave_four(
          {interleaved.data(), frames, rows.data(), kStride, sums, squares, peaks});
      EXPECT_LE(done, frames) << target;
      EXPECT_GT(done, frames - 32) << target;  // all but a partial step
      for (int c = 0; c < 4; ++c) {
        double want_sum = 0.0, want_square = 0.0, want_peak = 0.0;
        for (int n = 0; n < done; ++n) {
          const double value = interleaved[4 * static_cast<std::size_t>(n) + c];
          EXPECT_EQ(rows[static_cast<std::size_t>(c * kStride + n)], value) << target << c << n;
          want_sum += value;
          want_square += value * value;
          want_peak = std::max(want_peak, std::fabs(value));
        }
        EXPECT_EQ(rows[static_cast<std::size_t>(c * kStride + done)], -9.0) << target << c;
        EXPECT_NEAR(sums[c], want_sum, 1e-12 * frames) << target << c;
        EXPECT_NEAR(squares[c], want_square, 1e-12 * frames) << target << c;
        EXPECT_EQ(peaks[c], want_peak) << target << c;
      }
      if (frames >= 32) {
        EXPECT_EQ(peaks[3], 1.25) << target;
      }
    });
  }
}

// The acoustic features' bin assignment against the scalar rule it replaced: bins steered to
// one of two sources (and noise) go to that source with its steered power, the rest to nobody.
TEST(SimdKernels, SteeredBinsOwnerIsTheMostCoherentSource) {
  constexpr int kMics = 4, kSources = 2, kFirst = 37, kBins = 101;
  constexpr double kOmega = 2.0 * 3.141592653589793 * 48000.0 / 8192.0;
  const double delays[kSources][kMics] = {{0.0, 1.1e-3, -0.4e-3, 0.7e-3},
                                          {0.0, -0.9e-3, 0.8e-3, -0.2e-3}};
  std::mt19937 random(23);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<std::vector<std::complex<double>>> spectra(
      kMics, std::vector<std::complex<double>>(kFirst + kBins + 8));
  for (int k = kFirst; k < kFirst + kBins; ++k) {
    // Every third bin noise, the others a plane wave from source 0 or 1 (its steering undone).
    const int source = k % 3 == 0 ? -1 : (k / 7) % 2;
    const std::complex<double> amplitude(noise(random), noise(random));
    for (int m = 0; m < kMics; ++m) {
      std::complex<double> x(0.1 * noise(random), 0.1 * noise(random));
      if (source >= 0) x += amplitude * std::polar(1.0, -k * kOmega * delays[source][m]);
      if (k == kFirst + 5) x = 0.0;  // a silent bin owns nothing
      spectra[static_cast<std::size_t>(m)][static_cast<std::size_t>(k)] = x;
    }
  }
  constexpr double kMinCoherence = 0.3;
  std::vector<double> want_mic(kBins), want_source(kSources * kBins, 0.0);
  for (int k = kFirst; k < kFirst + kBins; ++k) {
    double energy = 0.0;
    for (int m = 0; m < kMics; ++m) energy += std::norm(spectra[static_cast<std::size_t>(m)][k]);
    want_mic[static_cast<std::size_t>(k - kFirst)] = energy / kMics;
    double best = kMinCoherence, power = 0.0;
    int owner = -1;
    for (int s = 0; s < kSources; ++s) {
      std::complex<double> sum = 0.0;
      for (int m = 0; m < kMics; ++m)
        sum += spectra[static_cast<std::size_t>(m)][k] * std::polar(1.0, k * kOmega * delays[s][m]);
      if (energy > 0.0 && std::norm(sum) >= best * kMics * energy) {
        best = std::norm(sum) / (kMics * energy);
        owner = s;
        power = std::norm(sum) / kMics;
      }
    }
    if (owner >= 0) want_source[static_cast<std::size_t>(owner * kBins + k - kFirst)] = power;
  }
  int owned = 0;
  for (const double power : want_source) owned += power > 0.0 ? 1 : 0;
  EXPECT_GT(owned, kBins / 2);  // the planted bins, not the noise ones
  const std::complex<double>* rows[kMics];
  for (int m = 0; m < kMics; ++m) rows[m] = spectra[static_cast<std::size_t>(m)].data();
  on_every_target([&](const std::string& target) {
    std::vector<double> mic(kBins, -1.0), source(kSources * kBins, -1.0);
    simd::steered_bins({rows, kMics, kFirst, kBins, kOmega, &delays[0][0], kMics, kSources,
                        kMinCoherence, mic.data(), source.data()});
    for (std::size_t i = 0; i < mic.size(); ++i)
      EXPECT_NEAR(mic[i], want_mic[i], 1e-12 * want_mic[i]) << target << i;
    for (std::size_t i = 0; i < source.size(); ++i) {
      EXPECT_EQ(source[i] > 0.0, want_source[i] > 0.0) << target << i;
      EXPECT_NEAR(source[i], want_source[i], 1e-9 * want_mic[i % kBins]) << target << i;
    }
  });
}

TEST(SimdKernels, ExponentialAverageBlendsTheFreshRow) {
  std::mt19937 random(31);
  std::normal_distribution<double> value(0.0, 1.0);
  constexpr double kKeep = 0.8;
  for (const std::size_t count : {std::size_t{1}, std::size_t{5}, std::size_t{684}}) {
    std::vector<double> average(count), fresh(count);
    for (std::size_t i = 0; i < count; ++i) {
      average[i] = value(random);
      fresh[i] = value(random);
    }
    on_every_target([&](const std::string& target) {
      std::vector<double> got = average;
      got.push_back(-7.0);
      simd::exponential_average({fresh.data(), got.data(), count, kKeep});
      for (std::size_t i = 0; i < count; ++i) {
        const double want = kKeep * average[i] + (1.0 - kKeep) * fresh[i];
        EXPECT_NEAR(got[i], want, 1e-15 * (std::abs(average[i]) + std::abs(fresh[i])))
            << target << i;
      }
      EXPECT_EQ(got[count], -7.0) << target << ": wrote past the row";
    });
  }
}

// The own-comb re-measure's steered cross-power: Re(a b* e^{j w k tdoa}) per FFT bin k of a run,
// added where kept; against cos and sin per bin, over a band run long enough (342 bins) for the
// rotation's error to build up.
TEST(SimdKernels, SteeredAgreementIsTheSteeredRealPart) {
  constexpr double kOmega = 2.0 * 3.141592653589793 * 48000.0 / 8192.0;
  std::mt19937 random(41);
  std::uniform_real_distribution<double> angle(-3.14159, 3.14159);
  std::exponential_distribution<double> size(1.0);
  for (const std::size_t count : {std::size_t{3}, std::size_t{342}}) {
    for (const double tdoa_s : {0.0, 1.7e-3, -2.3e-3}) {
      constexpr int kFirst = 267;
      std::vector<double> ar(count), ai(count), br(count), bi(count), magnitude(count);
      std::vector<std::uint8_t> keep(count);
      std::vector<double> power(count + 1), agreement(count + 1);
      for (std::size_t n = 0; n < count; ++n) {
        const double a = angle(random), b = angle(random);
        ar[n] = std::cos(a);
        ai[n] = std::sin(a);
        br[n] = std::cos(b);
        bi[n] = std::sin(b);
        magnitude[n] = size(random);
        keep[n] = n % 5 == 2 ? 0 : 1;
        power[n] = size(random);
        agreement[n] = angle(random);
      }
      power[count] = agreement[count] = -7.0;
      on_every_target([&](const std::string& target) {
        std::vector<double> got_power = power, got_agreement = agreement;
        simd::steered_agreement({count,
                                 static_cast<double>(kFirst),
                                 kOmega,
                                 tdoa_s,
                                 {ar.data(), ai.data()},
                                 {br.data(), bi.data()},
                                 magnitude.data(),
                                 keep.data(),
                                 got_power.data(),
                                 got_agreement.data()});
        for (std::size_t n = 0; n < count; ++n) {
          const std::complex<double> phasor =
              std::complex<double>(ar[n], ai[n]) * std::complex<double>(br[n], -bi[n]);
          const double turn = kOmega * static_cast<double>(kFirst + static_cast<int>(n)) * tdoa_s;
          const double want =
              keep[n] != 0 ? phasor.real() * std::cos(turn) - phasor.imag() * std::sin(turn) : 0.0;
          EXPECT_NEAR(got_agreement[n], agreement[n] + want, 1e-12) << target << n;
          EXPECT_NEAR(got_power[n], power[n] + magnitude[n] * want, 1e-12 * (1.0 + magnitude[n]))
              << target << n;
          if (keep[n] == 0) {
            EXPECT_EQ(got_agreement[n], agreement[n]) << target << n;
            EXPECT_EQ(got_power[n], power[n]) << target << n;
          }
        }
        EXPECT_EQ(got_power[count], -7.0) << target << ": wrote past the row";
        EXPECT_EQ(got_agreement[count], -7.0) << target << ": wrote past the row";
      });
    }
  }
}

// A source's bins (phasors e^{-j w_k tau_p} on every pair) are cleared and counted, others kept,
// bins already dropped stay dropped and uncounted; two runs of lengths that leave partial
// vectors on every width, with and without per-bin scales; nothing past the band is written.
TEST(SimdKernels, DropOwnedBinsClearsTheSourcesBins) {
  constexpr double kOmega = 2.0 * 3.141592653589793 * 48000.0 / 8192.0;
  constexpr int kPairs = 3;
  const std::array<BandRun, 2> runs{BandRun{101, 143}, BandRun{150, 186}};
  const std::size_t bins = 43 + 37;
  const std::array<double, kPairs> taus{1.1e-3, -0.4e-3, 2.3e-3};
  std::mt19937 random(43);
  std::uniform_real_distribution<double> angle(-3.14159, 3.14159);
  std::uniform_real_distribution<double> share(0.2, 1.0);
  std::vector<std::vector<std::complex<double>>> phasors(kPairs,
                                                         std::vector<std::complex<double>>(bins));
  std::vector<int> fft_bins;
  for (const BandRun& run : runs)
    for (int k = run.first_bin; k <= run.last_bin; ++k) fft_bins.push_back(k);
  std::vector<double> scales(bins);
  std::vector<std::uint8_t> keep(bins + 1, 1);
  keep[bins] = 7;
  for (std::size_t n = 0; n < bins; ++n) {
    const bool owned = n % 3 != 1;
    for (int p = 0; p < kPairs; ++p)
      phasors[static_cast<std::size_t>(p)][n] =
          owned ? std::polar(1.0, -kOmega * fft_bins[n] * taus[static_cast<std::size_t>(p)])
                : std::polar(1.0, angle(random));
    scales[n] = share(random);
    keep[n] = n % 7 == 3 ? 0 : 1;
  }
  const std::array<const std::complex<double>*, kPairs> rows{phasors[0].data(), phasors[1].data(),
                                                             phasors[2].data()};
  const double threshold = 0.5 * kPairs;
  for (const bool scaled : {false, true}) {
    std::vector<std::uint8_t> want = keep;
    int want_dropped = 0;
    std::vector<bool> decided(bins, true);
    for (std::size_t n = 0; n < bins; ++n) {
      double score = 0.0;
      for (int p = 0; p < kPairs; ++p)
        score += (phasors[static_cast<std::size_t>(p)][n] *
                  std::polar(1.0, kOmega * fft_bins[n] * taus[static_cast<std::size_t>(p)]))
                     .real();
      const double limit = threshold * (scaled ? scales[n] : 1.0);
      decided[n] = std::abs(score - limit) > 1e-9;  // the recurrence's rounding cannot flip it
      if (score >= limit && keep[n] != 0) {
        want[n] = 0;
        ++want_dropped;
      }
    }
    ASSERT_GT(want_dropped, 20);  // the source's bins, most of them
    ASSERT_LT(want_dropped, 60);  // not the others
    on_every_target([&](const std::string& target) {
      std::vector<std::uint8_t> got = keep;
      const int dropped =
          simd::drop_owned_bins({runs.data(), runs.size(), kOmega, rows.data(), taus.data(), kPairs,
                                 scaled ? scales.data() : nullptr, threshold, got.data()});
      EXPECT_EQ(dropped, want_dropped) << target;
      for (std::size_t n = 0; n < bins; ++n) {
        if (decided[n]) {
          EXPECT_EQ(got[n], want[n]) << target << " bin " << n;
        }
      }
      EXPECT_EQ(got[bins], 7) << target << ": wrote past the band";
    });
  }
}

// The static look's one pass against the four it stands for, on the same target: pair_products
// of the averaged phasors under the mask, drop_owned_bins per found source (one on every pair,
// one on two of three), kept_sums' weight scales and scale_and_sum. Phasors (double and
// single), magnitudes and keep bytes bit for bit; the magnitude sums to rounding (two band runs
// of lengths that leave partial vectors: the fused pass's lanes restart at each run).
TEST(SimdKernels, LookPhasorsIsTheFourPassesInOne) {
  constexpr double kOmega = 2.0 * 3.141592653589793 * 48000.0 / 8192.0;
  constexpr int kPairs = 3;
  const std::array<BandRun, 2> runs{BandRun{101, 143}, BandRun{150, 186}};
  const std::size_t bins = 43 + 37;
  const std::array<std::array<int, 2>, kPairs> mics{{{0, 1}, {0, 2}, {1, 2}}};
  const std::array<double, kPairs> taus_a{1.1e-3, -0.4e-3, -1.5e-3};
  const std::array<double, kPairs> taus_b{-0.7e-3, 0.9e-3, 1.6e-3};
  std::mt19937 random(29);
  std::uniform_real_distribution<double> angle(-3.14159, 3.14159);
  std::uniform_real_distribution<double> share(0.01, 1.0);
  std::vector<double> levels(3 * bins);
  for (double& level : levels) level = share(random);
  for (std::size_t n = 5; n < bins; n += 17) levels[n] = 0.0;  // mic 0 silent: no phase
  std::vector<std::vector<double>> given(kPairs, std::vector<double>(2 * bins));
  std::vector<double> weights(bins);
  std::vector<std::uint8_t> mask(bins + 1, 1);
  mask[bins] = 7;
  std::vector<double> omega2(bins);
  std::size_t at = 0;
  for (const BandRun& run : runs) {
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++at) {
      omega2[at] = (k * kOmega) * (k * kOmega);
      weights[at] = share(random);
      mask[at] = at % 7 == 3 ? 0 : 1;
      for (int p = 0; p < kPairs; ++p) {
        // A's bins, B's bins, noise; averaged phasors are shorter than 1, some 0.
        const double phase = at % 3 == 0   ? -kOmega * k * taus_a[static_cast<std::size_t>(p)]
                             : at % 3 == 1 ? -kOmega * k * taus_b[static_cast<std::size_t>(p)]
                                           : angle(random);
        const std::complex<double> value =
            at % 11 == 4 ? std::complex<double>{} : std::polar(share(random), phase);
        given[static_cast<std::size_t>(p)][2 * at] = value.real();
        given[static_cast<std::size_t>(p)][2 * at + 1] = value.imag();
      }
    }
  }
  const std::array<int, 5> term_pairs{0, 1, 2, 0, 2};
  const std::array<double, 5> term_taus{taus_a[0], taus_a[1], taus_a[2], taus_b[0], taus_b[2]};
  const std::array<int, 3> starts{0, 3, 5};
  const std::array<double, 2> thresholds{0.5 * 3, 0.5 * 2};
  on_every_target([&](const std::string& target) {
    // The four passes.
    std::vector<std::vector<double>> out(kPairs, std::vector<double>(2 * bins));
    std::vector<std::vector<float>> floats(kPairs, std::vector<float>(2 * bins));
    std::vector<std::vector<double>> magnitudes(kPairs, std::vector<double>(bins));
    std::vector<std::uint8_t> keep = mask;
    std::array<double, kPairs> sums{};
    for (std::size_t p = 0; p < kPairs; ++p) {
      const double* level_i = levels.data() + static_cast<std::size_t>(mics[p][0]) * bins;
      const double* level_j = levels.data() + static_cast<std::size_t>(mics[p][1]) * bins;
      simd::pair_products({{level_i, level_i},
                           {level_j, level_j},
                           level_i,
                           level_j,
                           keep.data(),
                           nullptr,
                           bins,
                           1e-30,
                           given[p].data(),
                           out[p].data(),
                           floats[p].data(),
                           magnitudes[p].data()});
    }
    const auto* rows = reinterpret_cast<const std::complex<double>*>(out[0].data());
    const std::array<const std::complex<double>*, 3> rows_a{
        rows, reinterpret_cast<const std::complex<double>*>(out[1].data()),
        reinterpret_cast<const std::complex<double>*>(out[2].data())};
    const std::array<const std::complex<double>*, 2> rows_b{rows_a[0], rows_a[2]};
    const int dropped_a =
        simd::drop_owned_bins({runs.data(), runs.size(), kOmega, rows_a.data(), term_taus.data(), 3,
                               nullptr, thresholds[0], keep.data()});
    const std::array<double, 2> b_taus{term_taus[3], term_taus[4]};
    const int dropped_b =
        simd::drop_owned_bins({runs.data(), runs.size(), kOmega, rows_b.data(), b_taus.data(), 2,
                               nullptr, thresholds[1], keep.data()});
    ASSERT_GT(dropped_a, 10) << target;  // not vacuous: both sources own bins
    ASSERT_GT(dropped_b, 10) << target;
    std::vector<double> scales(bins), keeps(bins);
    simd::kept_sums({keep.data(), weights.data(), omega2.data(), bins, true, simd::Rescale::weight,
                     scales.data(), keeps.data()});
    for (std::size_t p = 0; p < kPairs; ++p)
      sums[p] = simd::scale_and_sum({out[p].data(), floats[p].data(), magnitudes[p].data(),
                                     scales.data(), keeps.data(), weights.data(), true, bins});
    // The one pass.
    std::vector<std::vector<double>> fused(kPairs, std::vector<double>(2 * bins + 2, 9.0));
    std::vector<std::vector<float>> fused_floats(kPairs, std::vector<float>(2 * bins));
    std::vector<std::vector<double>> fused_magnitudes(kPairs, std::vector<double>(bins));
    std::vector<std::uint8_t> fused_keep = mask;
    std::array<double, kPairs> fused_sums{};
    std::array<const double*, kPairs> given_rows{}, level_i{}, level_j{};
    std::array<double*, kPairs> out_rows{}, magnitude_rows{};
    std::array<float*, kPairs> float_rows{};
    for (std::size_t p = 0; p < kPairs; ++p) {
      given_rows[p] = given[p].data();
      level_i[p] = levels.data() + static_cast<std::size_t>(mics[p][0]) * bins;
      level_j[p] = levels.data() + static_cast<std::size_t>(mics[p][1]) * bins;
      out_rows[p] = fused[p].data();
      float_rows[p] = fused_floats[p].data();
      magnitude_rows[p] = fused_magnitudes[p].data();
    }
    simd::look_phasors({runs.data(), runs.size(), kOmega, kPairs, given_rows.data(), level_i.data(),
                        level_j.data(), 1e-30, fused_keep.data(), weights.data(), term_pairs.data(),
                        term_taus.data(), starts.data(), 2, thresholds.data(), out_rows.data(),
                        float_rows.data(), magnitude_rows.data(), fused_sums.data()});
    EXPECT_EQ(fused_keep, keep) << target;
    EXPECT_EQ(fused_keep[bins], 7) << target << ": wrote past the band";
    for (std::size_t p = 0; p < kPairs; ++p) {
      for (std::size_t n = 0; n < 2 * bins; ++n) {
        EXPECT_EQ(fused[p][n], out[p][n]) << target << " pair " << p << " value " << n;
        EXPECT_EQ(fused_floats[p][n], floats[p][n]) << target << " pair " << p;
      }
      EXPECT_EQ(fused[p][2 * bins], 9.0) << target << ": wrote past the band";
      EXPECT_EQ(fused_magnitudes[p], magnitudes[p]) << target << " pair " << p;
      EXPECT_NEAR(fused_sums[p], sums[p], 1e-12 * sums[p]) << target << " pair " << p;
      EXPECT_GT(sums[p], 1.0) << target;  // live bins are left
    }
  });
}

TEST(SimdKernels, LaggedProductIsTheAutocorrelation) {
  std::mt19937 random(17);
  std::uniform_real_distribution<float> sample(0.0F, 2.0F);
  for (const int n : {5, 40, 333}) {
    std::vector<float> a(static_cast<std::size_t>(n));
    for (float& value : a) value = sample(random);
    for (const int lag : {0, 1, 3, n / 2, n - 1}) {
      double want = 0.0;
      for (int i = 0; i + lag < n; ++i) want += static_cast<double>(a[i]) * a[i + lag];
      on_every_target([&](const std::string& target) {
        EXPECT_NEAR(simd::lagged_product(a.data(), n, lag), want, 1e-6 * n * (1.0 + want))
            << target << " n " << n << " lag " << lag;
      });
    }
  }
}

}  // namespace
}  // namespace dronetrack::doa::simd_kernels_test
