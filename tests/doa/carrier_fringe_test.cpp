// A second direction beside a comb source: one of its carrier fringes (the source again) or a
// source of its own (carrier_fringe.hpp), on the mixed site's tetrahedron and rotor combs.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "doa/carrier_fringe.hpp"
#include "doa/harmonic_comb.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa::carrier_fringe_test {
namespace {

constexpr double kSoundMps = 343.0;
constexpr double kBinHz = 48000.0 / 2048.0;

// Every pair's lag (mic i's arrival minus mic j's) of a plane wave from `direction_site`.
std::vector<double> pair_lags_s(const ArrayGeometry& geometry, const Eigen::Vector3d& direction) {
  const std::vector<double> delays = testing::plane_wave_delays(geometry, direction, kSoundMps);
  std::vector<double> lags;
  for (std::size_t i = 0; i < delays.size(); ++i)
    for (std::size_t j = i + 1; j < delays.size(); ++j) lags.push_back(delays[i] - delays[j]);
  return lags;
}

// A power spectrum from bin 0: lines of `fundamental_hz` between low_hz and high_hz over a flat
// floor, each line 20 dB over it.
std::vector<double> comb_spectrum(double fundamental_hz, double low_hz, double high_hz, int bins) {
  std::vector<double> power(static_cast<std::size_t>(bins), 1.0);
  for (double f = fundamental_hz; f < high_hz; f += fundamental_hz) {
    if (f < low_hz) continue;
    const auto bin = static_cast<std::size_t>(std::lround(f / kBinHz));
    if (bin < power.size()) power[bin] = 100.0;
  }
  return power;
}

// The top mic's three pairs (0.667 m of height) move by one period of a 2.5 kHz carrier for
// ~11 deg of elevation: the fringe below a source at 16 deg lies within one fringe of it, a
// direction 30 deg off does not, and at a 10 kHz carrier neither does the 11 deg one (its
// fringes are four times narrower).
TEST(CarrierFringe, TheNeighbouringFringeIsWithinOneCarrierPeriodOnEveryPair) {
  const ArrayGeometry geometry = testing::tetrahedron(45.0);
  const std::vector<double> source = pair_lags_s(geometry, direction_from_azel_deg(80.0, 16.0));
  const std::vector<double> fringe = pair_lags_s(geometry, direction_from_azel_deg(80.0, 5.0));
  const std::vector<double> far = pair_lags_s(geometry, direction_from_azel_deg(80.0, -14.0));
  double largest_s = 0.0;
  for (std::size_t p = 0; p < source.size(); ++p)
    largest_s = std::max(largest_s, std::abs(fringe[p] - source[p]));
  // One carrier period at 2.5 kHz is 0.4 ms: the 11 deg step is about one.
  EXPECT_GT(largest_s, 0.7 / 2500.0);
  EXPECT_LT(largest_s, 1.3 / 2500.0);
  EXPECT_TRUE(within_one_carrier_fringe(source, fringe, 2500.0));
  EXPECT_FALSE(within_one_carrier_fringe(source, far, 2500.0));
  EXPECT_FALSE(within_one_carrier_fringe(source, fringe, 10000.0));
  EXPECT_FALSE(within_one_carrier_fringe(source, fringe, 0.0));
}

// The carrier of a rotor's lines 1-4 kHz is their power-weighted mean, nearer the louder end.
TEST(CarrierFringe, CarrierIsThePowerWeightedMeanOfTheLines) {
  const int bins = 200;
  std::vector<double> power(static_cast<std::size_t>(bins), 0.0);
  std::vector<std::uint8_t> on_line(static_cast<std::size_t>(bins), 0);
  power[100] = 3.0;   // 2344 Hz
  power[120] = 1.0;   // 2813 Hz
  power[110] = 50.0;  // not a line: left out
  on_line[100] = on_line[120] = 1;
  EXPECT_NEAR(comb_carrier_hz(power, on_line, 0, kBinHz), 105.0 * kBinHz, 1e-9);
  // Bins counted from first_bin.
  EXPECT_NEAR(comb_carrier_hz(power, on_line, 10, kBinHz), 115.0 * kBinHz, 1e-9);
  std::fill(on_line.begin(), on_line.end(), 0);
  EXPECT_EQ(comb_carrier_hz(power, on_line, 0, kBinHz), 0.0);
}

// What a fringe of D1 (150 Hz, 18 lines in 1-4 kHz) shows: its lines near the carrier only (the
// same spacing), or no comb; a second drone there shows its own 205 Hz comb.
TEST(CarrierFringe, AFringeShowsTheSourcesCombOrNoneAndASecondDroneItsOwn) {
  const int bins = 200;  // 0-4.7 kHz
  HarmonicCombDetector detector(0, bins, kBinHz);
  std::vector<std::uint8_t> lines(static_cast<std::size_t>(bins), 0);
  const auto measure = [&](const std::vector<double>& power) {
    HarmonicComb comb = detector.analyse(power);
    comb.harmonic_count = detector.mark_lines(comb, lines);
    return comb;
  };
  const HarmonicComb source = measure(comb_spectrum(150.0, 1000.0, 4000.0, bins));
  ASSERT_TRUE(source.found);
  ASSERT_NEAR(source.fundamental_hz, 150.0, 0.5 * kBinHz);
  const HarmonicComb near_carrier = measure(comb_spectrum(150.0, 2300.0, 3100.0, bins));
  const HarmonicComb second_drone = measure(comb_spectrum(205.0, 1000.0, 4000.0, bins));
  ASSERT_TRUE(second_drone.found);
  const HarmonicComb broadband = measure(std::vector<double>(static_cast<std::size_t>(bins), 1.0));
  const int min_lines = 4;
  const double tolerance_hz = 0.5 * kBinHz;
  EXPECT_TRUE(comb_is_the_sources(source, near_carrier, min_lines, tolerance_hz));
  EXPECT_TRUE(comb_is_the_sources(source, broadband, min_lines, tolerance_hz));
  EXPECT_FALSE(comb_is_the_sources(source, second_drone, min_lines, tolerance_hz));
}

}  // namespace
}  // namespace dronetrack::doa::carrier_fringe_test
