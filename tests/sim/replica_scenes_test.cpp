// The replicas of seeds 000, 003 and 004 (config/scenarios/, docs/replicas.md): the papers'
// setup (1500 m/s, 100 kHz, a moving pair 0.6 m apart whose yaw follows its heading, the bands),
// and their rendered sound: the delay between the two hydrophones, measured by correlation in
// each source's band, is the one the geometry gives at that moment.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "sim_test_util.hpp"

namespace dronetrack::sim::replica_scenes_test {
namespace {

using test::channel;
using test::correlation_peak_lag;

std::filesystem::path replica(const std::string& name) {
  return std::filesystem::path(DRONETRACK_SOURCE_DIR) / "config/scenarios" / name;
}

class ReplicaScene : public ::testing::TestWithParam<const char*> {};

TEST_P(ReplicaScene, IsThePapersHydrophonePairUnderWater) {
  std::vector<std::string> warnings;
  const Scenario scenario = load_scenario(replica(GetParam()), warnings);
  EXPECT_TRUE(warnings.empty()) << (warnings.empty() ? "" : warnings[0]);
  EXPECT_EQ(scenario.site.speed_of_sound_mps, 1500.0);
  EXPECT_EQ(scenario.sample_rate_hz, 100000.0);
  ASSERT_EQ(scenario.site.arrays.size(), 1u);
  const auto& geometry = scenario.site.arrays[0].geometry;
  ASSERT_EQ(geometry.mic_count(), 2u);
  EXPECT_NEAR((geometry.mics_m[0] - geometry.mics_m[1]).norm(), 0.6, 1e-12);
  ASSERT_TRUE(scenario.moving_arrays.at(0).has_value());
  EXPECT_EQ(scenario.moving_arrays[0]->motion.yaw_mode, YawMode::heading);
  // Every band is at least 9 kHz wide (narrower, the GCC's envelope spans the whole +-400 us
  // lag range of a 0.6 m pair and its carrier fringes compete) and below 0.4 x 100 kHz.
  for (const auto& band : scenario.site.doa.bands_hz) {
    EXPECT_GE(band.high_hz - band.low_hz, 9000.0);
    EXPECT_GE(band.low_hz, 10000.0);
    EXPECT_LE(band.high_hz, 40000.0);
  }
}

TEST_P(ReplicaScene, DirectPathDelayBetweenTheHydrophonesMatchesTheGeometry) {
  std::vector<std::string> warnings;
  Scenario scenario = load_scenario(replica(GetParam()), warnings);
  // The first 3 s, direct path only: no interferer, no seabed echo, no noise (they are there
  // for the DOA stage to cope with, not part of the geometry being checked).
  scenario.duration_s = 3.0;
  scenario.ground_reflection = 0.0;
  scenario.noise = NoiseSpec{};
  std::erase_if(scenario.sources,
                [](const SourceSpec& source) { return source.kind == SourceKind::interferer; });
  const RenderedArray rendered = render_array(scenario, 0);
  const double c = scenario.site.speed_of_sound_mps;
  const double rate_hz = scenario.sample_rate_hz;
  const auto& mics = scenario.site.arrays[0].geometry.mics_m;
  const ArrayMotion& motion = scenario.moving_arrays[0]->motion;
  const auto window = static_cast<std::size_t>(0.2 * rate_hz);
  for (const auto& source : scenario.sources) {
    const Eigen::Vector3d position = source.trajectory.position(0.0);
    for (double centre_s : {0.8, 2.2}) {
      // The sound reaching mic 1 at the window's centre left at t_e; it reaches mic 0 at t0
      // with |s - m0(t0)| = c (t0 - t_e) (fixed point: contracts by v / c per step).
      const double t1 = centre_s;
      const double emission_s =
          t1 - (position - motion.point_state(mics[1], t1).position_m).norm() / c;
      double t0 = t1;
      for (int step = 0; step < 8; ++step)
        t0 = emission_s + (position - motion.point_state(mics[0], t0).position_m).norm() / c;
      const double expected_s = t0 - t1;
      // The two mics' distances at one instant: off by the ~0.4 mm the pair moves during the
      // delay (0.2 us near endfire), which is why the exact value is used above.
      const double instant_s = ((position - motion.point_state(mics[0], t1).position_m).norm() -
                                (position - motion.point_state(mics[1], t1).position_m).norm()) /
                               c;
      const auto begin = static_cast<std::size_t>(centre_s * rate_hz) - window / 2;
      const double measured_s =
          correlation_peak_lag(channel(rendered, 0, begin, begin + window),
                               channel(rendered, 1, begin, begin + window), expected_s * rate_hz,
                               3.0, source.noise.low_hz, source.noise.high_hz, rate_hz) /
          rate_hz;
      std::printf("%s %s at %.1f s: TDOA %.3f us measured, %.3f us exact, %.3f us instantaneous\n",
                  GetParam(), source.id.c_str(), centre_s, measured_s * 1e6, expected_s * 1e6,
                  instant_s * 1e6);
      EXPECT_NEAR(measured_s, expected_s, 0.05e-6) << source.id << " at " << centre_s << " s";
      EXPECT_NEAR(measured_s, instant_s, 0.5e-6) << source.id << " at " << centre_s << " s";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, ReplicaScene,
                         ::testing::Values("seed000-moving-pair.json", "seed003-three-sources.json",
                                           "seed004-multipeak.json"));

}  // namespace
}  // namespace dronetrack::sim::replica_scenes_test
