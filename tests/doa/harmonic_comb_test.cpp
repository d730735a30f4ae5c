// HarmonicCombDetector on real rotor sound (../shared/data/drone-sounds/) and on non-drone
// sounds made here at the same in-band SNR: a mains-locked generator, a car (engine harmonics
// that die out above 1 kHz, tyre broadband), and broadband noise.
#include <gtest/gtest.h>
#include <sndfile.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <vector>

#include "doa/doa_params.hpp"
#include "doa/harmonic_comb.hpp"
#include "doa/spectral_frame.hpp"

namespace dronetrack::doa::harmonic_comb_test {
namespace {

constexpr double kPi = std::numbers::pi;

std::vector<double> read_mono(const std::filesystem::path& file, double& rate_hz) {
  SF_INFO info{};
  SNDFILE* handle = sf_open(file.c_str(), SFM_READ, &info);
  if (handle == nullptr) return {};
  std::vector<double> interleaved(static_cast<std::size_t>(info.frames * info.channels));
  sf_readf_double(handle, interleaved.data(), info.frames);
  sf_close(handle);
  std::vector<double> mono(static_cast<std::size_t>(info.frames));
  for (std::size_t i = 0; i < mono.size(); ++i)
    mono[i] = interleaved[i * static_cast<std::size_t>(info.channels)];
  rate_hz = info.samplerate;
  return mono;
}

std::filesystem::path drone_sound(const char* name) {
  return std::filesystem::path(DRONETRACK_SOURCE_DIR) / "../shared/data/drone-sounds" / name;
}

// White noise added so the band [low_hz, high_hz] has the given SNR (power of the signal in the
// band over the noise's power in the band).
void add_noise_at_snr(std::vector<double>& signal, double rate_hz, double low_hz, double high_hz,
                      double snr_db, unsigned seed) {
  // In-band power of the signal: mean over 8192-sample frames (Parseval on the band's bins).
  const int n = 8192;
  MultichannelFft fft(1, n, n);
  double band_power = 0.0;
  int frames = 0;
  for (std::size_t start = 0; start + n <= signal.size(); start += n, ++frames) {
    FrameView frame;
    frame.channels = 1;
    frame.length = n;
    frame.samples = signal.data() + start;
    fft.process(frame);
    const double bin_hz = rate_hz / n;
    for (int k = static_cast<int>(low_hz / bin_hz); k <= static_cast<int>(high_hz / bin_hz); ++k)
      band_power += std::norm(fft.spectrum(0)[k]);
  }
  band_power *= 2.0 / (static_cast<double>(n) * fft.window_energy() * std::max(frames, 1));
  const double noise_power = band_power / std::pow(10.0, snr_db / 10.0);
  // White noise of variance v has in-band power v * 2 (high - low) / rate.
  const double variance = noise_power * rate_hz / (2.0 * (high_hz - low_hz));
  std::mt19937 random(seed);
  std::normal_distribution<double> normal(0.0, std::sqrt(variance));
  for (double& x : signal) x += normal(random);
}

struct CombRun {
  int frames = 0;
  int combs = 0;
  std::vector<double> fundamentals_hz;
  double median_fundamental_hz() {
    if (fundamentals_hz.empty()) return 0.0;
    std::sort(fundamentals_hz.begin(), fundamentals_hz.end());
    return fundamentals_hz[fundamentals_hz.size() / 2];
  }
  double comb_share() const { return frames > 0 ? static_cast<double>(combs) / frames : 0.0; }
  double drone_share = 0.0;  // frames whose comb lies in the drone range 80-400 Hz
};

// Frames of 0.17 s, analysed every 0.3 s into a mean autocorrelation of 1 s memory (the node's
// defaults: doa/acoustic_features.hpp); counts the analyses with a comb.
CombRun run_detector(const std::vector<double>& signal, double rate_hz, double low_hz,
                     double high_hz) {
  const int frame = static_cast<int>(std::lround(0.17 * rate_hz));
  const int hop = static_cast<int>(std::lround(0.05 * rate_hz));
  const int fft_size = fftw_friendly_size(frame);
  MultichannelFft fft(1, frame, fft_size);
  const double bin_hz = rate_hz / fft_size;
  const int first_bin = static_cast<int>(std::ceil(low_hz / bin_hz));
  const int last_bin = static_cast<int>(std::floor(high_hz / bin_hz));
  HarmonicCombDetector detector(first_bin, last_bin - first_bin + 1, bin_hz);
  std::vector<double> power(static_cast<std::size_t>(last_bin - first_bin + 1));
  std::vector<double> frame_autocorrelation(static_cast<std::size_t>(detector.lag_count()));
  std::vector<double> mean_autocorrelation(frame_autocorrelation.size());
  CombRun run;
  int drone_like = 0;
  // As the node does it (doa::AcousticSettings' defaults): every few frames, into a mean of
  // comb_memory_s memory.
  const AcousticSettings defaults;
  const double weight =
      std::min(1.0, defaults.analysis_every_frames * 0.05 / defaults.comb_memory_s);
  bool started = false;
  for (std::size_t start = 0; start + static_cast<std::size_t>(frame) <= signal.size();
       start += static_cast<std::size_t>(defaults.analysis_every_frames * hop)) {
    FrameView view;
    view.channels = 1;
    view.length = frame;
    view.samples = signal.data() + start;
    fft.process(view);
    for (int k = first_bin; k <= last_bin; ++k)
      power[static_cast<std::size_t>(k - first_bin)] = std::norm(fft.spectrum(0)[k]);
    detector.autocorrelate(power, frame_autocorrelation);
    for (std::size_t l = 0; l < frame_autocorrelation.size(); ++l)
      mean_autocorrelation[l] +=
          (started ? weight : 1.0) * (frame_autocorrelation[l] - mean_autocorrelation[l]);
    started = true;
    const HarmonicComb comb = detector.find(mean_autocorrelation);
    ++run.frames;
    if (!comb.found) continue;
    ++run.combs;
    run.fundamentals_hz.push_back(comb.fundamental_hz);
    if (comb.fundamental_hz >= 80.0 && comb.fundamental_hz <= 400.0) ++drone_like;
  }
  run.drone_share = run.frames > 0 ? static_cast<double>(drone_like) / run.frames : 0.0;
  return run;
}

// Harmonics of `fundamental_hz` below 4 kHz, amplitude(f) each, random phases.
std::vector<double> harmonic_series(double rate_hz, double seconds, double fundamental_hz,
                                    double (*amplitude)(double), unsigned seed) {
  std::vector<double> out(static_cast<std::size_t>(rate_hz * seconds));
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> phase(0.0, 2.0 * kPi);
  for (int h = 1; h * fundamental_hz < 4000.0; ++h) {
    const double f = fundamental_hz * h;
    const double a = amplitude(f);
    const double phi = phase(random);
    for (std::size_t i = 0; i < out.size(); ++i)
      out[i] += a * std::sin(2.0 * kPi * f * static_cast<double>(i) / rate_hz + phi);
  }
  return out;
}

// A generator locked to 50 Hz mains: its harmonics (firing and mechanical) to 4 kHz with a
// -6 dB/octave slope.
std::vector<double> generator(double rate_hz, double seconds, unsigned seed) {
  return harmonic_series(
      rate_hz, seconds, 50.0, [](double f) { return 50.0 / f; }, seed);
}

// A car: a four-cylinder engine at 1800 rpm (60 Hz firing) whose harmonics fall 24 dB per
// octave above 500 Hz, under tyre noise that fills the band (white noise, dominant in band).
std::vector<double> car(double rate_hz, double seconds, unsigned seed) {
  std::vector<double> out = harmonic_series(
      rate_hz, seconds, 60.0, [](double f) { return f <= 500.0 ? 1.0 : std::pow(500.0 / f, 4.0); },
      seed);
  std::mt19937 random(seed + 1);
  std::normal_distribution<double> tyre(0.0, 0.3);
  for (double& x : out) x += tyre(random);
  return out;
}

// The node's default feature band (doa.acoustic.band_hz): in 1.5-3.5 kHz the four rotors' combs
// of a real quadcopter smear (harmonics 9-19 of slightly different speeds); from 800 Hz up the
// comb is found in 56-100 % of the clips' analyses instead of 16-96 %.
const double kBandLowHz = 800.0;
const double kBandHighHz = 3500.0;
constexpr double kSnrDb = 10.0;

TEST(HarmonicComb, FindsTheRotorFundamentalOnRealDroneRecordings) {
  // The clips with a ~180 Hz blade-passage series (README of the data set), 021 whose lines sit at
  // ~98 Hz and on a ~180 Hz series (two rotor speeds: the spacing found wanders between them), and
  // the three whose dominant line is ~355-400 Hz.
  struct Clip {
    const char* name;
    double low_hz;
    double high_hz;
  };
  const Clip clips[] = {{"ddd_drone_003_ch0.wav", 170, 200}, {"ddd_drone_017_ch0.wav", 170, 200},
                        {"ddd_drone_021_ch0.wav", 80, 400},  {"ddd_drone_014_ch0.wav", 80, 400},
                        {"ddd_drone_024_ch0.wav", 80, 400},  {"ddd_drone_029_ch0.wav", 80, 400}};
  double drone_share_sum = 0.0;
  for (const Clip& clip : clips) {
    double rate_hz = 0.0;
    std::vector<double> signal = read_mono(drone_sound(clip.name), rate_hz);
    if (signal.empty()) GTEST_SKIP() << clip.name << " not present";
    add_noise_at_snr(signal, rate_hz, kBandLowHz, kBandHighHz, kSnrDb, 7);
    CombRun run = run_detector(signal, rate_hz, kBandLowHz, kBandHighHz);
    const double median = run.median_fundamental_hz();
    std::printf("%s: comb in %.1f %% of %d frames, drone-range %.1f %%, median f0 %.1f Hz\n",
                clip.name, 100.0 * run.comb_share(), run.frames, 100.0 * run.drone_share, median);
    // Per 0.3-s analysis; the classifier votes over seconds (fusion/track_classifier.hpp).
    EXPECT_GE(run.drone_share, 0.4) << clip.name;
    drone_share_sum += run.drone_share;
    EXPECT_GE(median, clip.low_hz) << clip.name;
    EXPECT_LE(median, clip.high_hz) << clip.name;
  }
  EXPECT_GE(drone_share_sum / 6.0, 0.7);
}

TEST(HarmonicComb, RejectsGeneratorCarAndNoiseAtTheSameSnr) {
  const double rate_hz = 48000.0;
  struct Sound {
    const char* name;
    std::vector<double> samples;
  };
  Sound sounds[] = {{"generator", generator(rate_hz, 4.0, 1)},
                    {"car", car(rate_hz, 4.0, 2)},
                    {"noise", std::vector<double>(static_cast<std::size_t>(4.0 * rate_hz), 0.0)}};
  {
    std::mt19937 random(3);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (double& x : sounds[2].samples) x = normal(random);
  }
  for (Sound& sound : sounds) {
    add_noise_at_snr(sound.samples, rate_hz, kBandLowHz, kBandHighHz, kSnrDb, 11);
    CombRun run = run_detector(sound.samples, rate_hz, kBandLowHz, kBandHighHz);
    std::printf("%s: comb in %.1f %% of %d frames, drone-range %.1f %%, median f0 %.1f Hz\n",
                sound.name, 100.0 * run.comb_share(), run.frames, 100.0 * run.drone_share,
                run.median_fundamental_hz());
    EXPECT_LE(run.drone_share, 0.05) << sound.name;
  }
}

// mark_lines() keeps a rotor's lines and nothing between them, even where a generator's 50 Hz
// comb is as loud: the bins the node measures a comb source's TDOAs on (own_comb_bins).
TEST(HarmonicComb, MarksTheCombsLinesAndNotTheGaps) {
  const double bin_hz = 48000.0 / 8192.0;
  const int first_bin = 256;  // 1.5 kHz
  const int bins = 342;       // to 3.5 kHz
  HarmonicCombDetector detector(first_bin, bins, bin_hz);
  std::mt19937 random(5);
  std::exponential_distribution<double> floor(1.0);
  std::vector<double> power(static_cast<std::size_t>(bins));
  for (double& p : power) p = floor(random);
  const double rotor_hz = 205.0;
  std::vector<int> rotor_lines;
  for (int h = 8; h <= 17; ++h) {
    const int line = static_cast<int>(std::lround(h * rotor_hz / bin_hz)) - first_bin;
    rotor_lines.push_back(line);
    power[static_cast<std::size_t>(line)] += 1000.0;
  }
  std::vector<std::uint8_t> on_line(static_cast<std::size_t>(bins), 7);
  const HarmonicComb rotor = detector.analyse(power);
  ASSERT_TRUE(rotor.found);
  EXPECT_NEAR(rotor.fundamental_hz, rotor_hz, 2.0);
  EXPECT_EQ(detector.mark_lines(rotor, on_line), 10);
  for (int i = 0; i < bins; ++i) {
    bool near_line = false;
    for (const int line : rotor_lines) near_line = near_line || std::abs(i - line) <= 1;
    EXPECT_EQ(on_line[static_cast<std::size_t>(i)], near_line ? 1 : 0) << "bin " << i;
  }
  // Broadband only: no comb, nothing marked.
  for (double& p : power) p = floor(random);
  const HarmonicComb none = detector.analyse(power);
  EXPECT_FALSE(none.found);
  EXPECT_EQ(detector.mark_lines(none, on_line), 0);
  EXPECT_EQ(std::count(on_line.begin(), on_line.end(), std::uint8_t{1}), 0);
}

// detect() skips the autocorrelation when too few bins stand out to make a comb: it must find
// exactly the combs analyse() finds, with the same lines, on spectra of every kind the node
// gives it: noise alone, noise with a few strong bins, combs down to the smallest spacing
// searched (where a bin lies in two lines' windows), lines near the salience threshold, and
// other sources' bins masked out (power 0).
TEST(HarmonicComb, DetectFindsExactlyTheCombsAnalyseFinds) {
  const double bin_hz = 48000.0 / 4096.0;
  const int first_bin = 9;
  const int bins = 330;
  HarmonicCombDetector analysed(first_bin, bins, bin_hz);
  HarmonicCombDetector detected(first_bin, bins, bin_hz);
  std::mt19937 random(17);
  std::gamma_distribution<double> floor(4.0, 1.0);  // four mics' summed |X|^2
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> power(static_cast<std::size_t>(bins));
  std::vector<std::uint8_t> lines_analysed(static_cast<std::size_t>(bins));
  std::vector<std::uint8_t> lines_detected(static_cast<std::size_t>(bins));
  int combs = 0;
  int skipped_kinds = 0;
  for (int trial = 0; trial < 600; ++trial) {
    for (double& p : power) p = floor(random);
    const int kind = trial % 4;
    if (kind == 1) {  // a few loud bins, no comb
      const int loud = static_cast<int>(unit(random) * 3.0);
      for (int i = 0; i < loud; ++i)
        power[static_cast<std::size_t>(unit(random) * (bins - 1))] *= 20.0;
      ++skipped_kinds;
    }
    if (kind >= 2) {  // a comb, 2.5-40 bins apart, lines 3-12 dB over the floor
      const double spacing = 2.5 + unit(random) * 37.5;
      const double gain = std::pow(10.0, (3.0 + unit(random) * 9.0) / 10.0);
      for (double bin = spacing * std::ceil(first_bin / spacing);
           std::lround(bin) < first_bin + bins; bin += spacing)
        power[static_cast<std::size_t>(std::lround(bin)) - first_bin] *= gain * 2.0;
    }
    if (kind == 3) {  // another source's bins taken out
      const int start = static_cast<int>(unit(random) * (bins - 60));
      std::fill(power.begin() + start, power.begin() + start + 60, 0.0);
    }
    const HarmonicComb expected = analysed.analyse(power);
    const HarmonicComb comb = detected.detect(power);
    ASSERT_EQ(comb.found, expected.found) << "trial " << trial;
    combs += comb.found ? 1 : 0;
    if (!expected.found) continue;
    EXPECT_EQ(comb.fundamental_hz, expected.fundamental_hz) << "trial " << trial;
    EXPECT_EQ(comb.harmonic_count, expected.harmonic_count) << "trial " << trial;
    EXPECT_EQ(analysed.mark_lines(expected, lines_analysed),
              detected.mark_lines(comb, lines_detected));
    EXPECT_EQ(lines_analysed, lines_detected) << "trial " << trial;
  }
  // Both branches taken: combs found, and spectra without one.
  EXPECT_GT(combs, 100);
  EXPECT_LT(combs, 450);
  EXPECT_GT(skipped_kinds, 100);
}

}  // namespace
}  // namespace dronetrack::doa::harmonic_comb_test
