// The simulator's non-drone sources (issue 14): their physics, checked on what one mic hears
// (static source 20 m away, no noise): an engine's firing harmonics and tyre broadband, a
// generator locked to the mains, a propeller's comb, birdsong chirps with gaps.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/render.hpp"
#include "sim/scenario.hpp"
#include "sim_test_util.hpp"

namespace dronetrack::sim::source_types_test {
namespace {

using nlohmann::json;

std::vector<double> heard(const json& signal, double duration_s = 2.0) {
  const json source = {{"id", "X1"},
                       {"kind", "interferer"},
                       {"level_db", 90},
                       {"signal", signal},
                       {"trajectory", {{"type", "static"}, {"position_m", {20.0, 0.0, 1.5}}}}};
  const Scenario scenario = parse_scenario(test::scene(source, duration_s), ".");
  return test::channel(render_array(scenario, 0), 0);
}

// Power within +-2 Hz of f over the power within the +-20 Hz around it (a line stands out).
double line_prominence(const std::vector<double>& x, double frequency_hz) {
  const double line = test::band_power(x, frequency_hz - 2.0, frequency_hz + 2.0);
  const double around = test::band_power(x, frequency_hz - 20.0, frequency_hz + 20.0);
  return line / std::max(around - line, 1e-30);
}

TEST(SourceTypes, EngineHasFiringHarmonicsThatDieOutAndTyreBroadband) {
  const std::vector<double> x = heard({{"type", "engine"}});  // 60 Hz firing, corner 500 Hz
  EXPECT_GT(line_prominence(x, 60.0), 10.0);
  EXPECT_GT(line_prominence(x, 120.0), 10.0);
  // Above the corner the harmonics are 18 dB/octave weaker: tyre noise fills 1.5-3.5 kHz.
  const double low_band = test::band_power(x, 100.0, 500.0);
  const double high_band = test::band_power(x, 1500.0, 3500.0);
  EXPECT_GT(high_band, 0.01 * low_band);
  EXPECT_LT(line_prominence(x, 2400.0), 3.0);
}

TEST(SourceTypes, GeneratorIsLockedToTheMains) {
  const std::vector<double> x = heard({{"type", "generator"}, {"mains_hz", 60.0}}, 4.0);
  for (double f : {60.0, 120.0, 180.0, 300.0}) EXPECT_GT(line_prominence(x, f), 3.0) << f;
  // Locked: the line in the first and the last second within 0.2 Hz (0.5 Hz FFT bins here).
  const std::size_t second = 48000;
  const std::vector<double> first(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(second));
  const std::vector<double> last(x.end() - static_cast<std::ptrdiff_t>(second), x.end());
  for (const auto* part : {&first, &last}) {
    const double centre = test::band_power(*part, 59.0, 61.0);
    const double around = test::band_power(*part, 55.0, 65.0);
    EXPECT_GT(centre, 0.8 * around);
  }
}

TEST(SourceTypes, PropellerIsACombOfItsBladePassage) {
  const std::vector<double> x = heard({{"type", "propeller"}, {"rpm_wander", 0.0}});
  for (double f : {85.0, 170.0, 255.0, 850.0}) EXPECT_GT(line_prominence(x, f), 3.0) << f;
}

TEST(SourceTypes, ChirpsAreSweepsInTheirBandWithGaps) {
  const std::vector<double> x =
      heard({{"type", "chirps"}, {"low_hz", 3000.0}, {"high_hz", 5000.0}}, 6.0);
  const double in_band = test::band_power(x, 2900.0, 5100.0);
  const double total = test::band_power(x, 20.0, 19000.0);
  EXPECT_GT(in_band, 0.95 * total);
  // Silent stretches between chirps: some 50 ms windows hold (almost) nothing, some a chirp.
  int silent = 0;
  int loud = 0;
  for (std::size_t start = 0; start + 2400 <= x.size(); start += 2400) {
    double energy = 0.0;
    for (std::size_t n = start; n < start + 2400; ++n) energy += x[n] * x[n];
    if (energy < 1e-12) ++silent;
    if (energy > 1e-6) ++loud;
  }
  EXPECT_GT(silent, 5);
  EXPECT_GT(loud, 5);
  // The same samples whatever range is rendered (deterministic per seed and source).
  const std::vector<double> longer =
      heard({{"type", "chirps"}, {"low_hz", 3000.0}, {"high_hz", 5000.0}}, 8.0);
  for (std::size_t n = 0; n < x.size() - 48000; n += 997) EXPECT_EQ(x[n], longer[n]) << n;
}

TEST(SourceTypes, ClassMustFitTheKind) {
  json source = {{"id", "D1"},
                 {"kind", "drone"},
                 {"class", "aircraft"},
                 {"trajectory", {{"type", "static"}, {"position_m", {20.0, 0.0, 30.0}}}}};
  try {
    parse_scenario(test::scene(source), ".");
    FAIL() << "accepted a drone of class aircraft";
  } catch (const config::ConfigError& error) {
    EXPECT_NE(std::string(error.what()).find("sources[0].class"), std::string::npos)
        << error.what();
  }
}

}  // namespace
}  // namespace dronetrack::sim::source_types_test
