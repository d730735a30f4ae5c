// Whole scenes: noise levels against the requested SNR, clipping, determinism, the files.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <sndfile.h>

#include "config/site_config.hpp"
#include "sim_test_util.hpp"

namespace dronetrack::sim::scene_test {
namespace {

using nlohmann::json;
using test::band_power;
using test::channel;

json drone(double x = 30.0) {
  return {
      {"id", "D1"},
      {"level_db", 85},
      {"signal", {{"type", "rotor"}, {"blade_pass_hz", 170}}},
      {"trajectory",
       {{"type", "straight"}, {"start_m", {x, -10.0, 20.0}}, {"velocity_mps", {0.0, 6.0, 0.0}}}}};
}

// In-band SNR measured independently: the same scene without noise gives the signal; the
// difference is the noise. Averaged over the mics, band 1500-3500 Hz.
double measured_snr_db(const json& noise) {
  json document = test::scene(drone(), 3.0);
  const RenderedArray clean = render_array(parse_scenario(document, "."), 0);
  document["noise"] = noise;
  const RenderedArray noisy = render_array(parse_scenario(document, "."), 0);
  double signal = 0.0, noise_power = 0.0;
  for (std::size_t mic = 0; mic < 4; ++mic) {
    const auto s = channel(clean, mic);
    auto n = channel(noisy, mic);
    for (std::size_t i = 0; i < n.size(); ++i) n[i] -= s[i];
    signal += band_power(s, 1500, 3500);
    noise_power += band_power(n, 1500, 3500);
  }
  return 10.0 * std::log10(signal / noise_power);
}

TEST(Scene, InBandSnrIsWithinOneDecibelOfRequested) {
  EXPECT_NEAR(measured_snr_db({{"sensor", {{"snr_db", 10}}}}), 10.0, 1.0);
  EXPECT_NEAR(measured_snr_db({{"ambient", {{"snr_db", 0}}}}), 0.0, 1.0);
  EXPECT_NEAR(measured_snr_db({{"wind", {{"snr_db", 20}}}}), 20.0, 1.0);
  // Two components at 13 dB each: 10 dB together.
  EXPECT_NEAR(measured_snr_db({{"sensor", {{"snr_db", 13}}}, {"ambient", {{"snr_db", 13}}}}), 10.0,
              1.0);
}

TEST(Scene, AbsoluteNoiseLevelIsInDecibelsSpl) {
  json document = test::scene({{"id", "G"},
                               {"kind", "interferer"},
                               {"level_db", 0},
                               {"trajectory", {{"type", "hover"}, {"position_m", {100, 0, 0.5}}}}},
                              2.0);
  document["noise"] = {{"sensor", {{"level_db", 40}}}};  // 120 dB SPL full scale: rms 1e-4
  const RenderedArray array = render_array(parse_scenario(document, "."), 0);
  double power = 0.0;
  for (float value : array.samples) power += static_cast<double>(value) * value;
  power /= static_cast<double>(array.samples.size());
  EXPECT_NEAR(10.0 * std::log10(power), -80.0, 0.1);
}

TEST(Scene, WindIsLowFrequencyAndIndependentPerMic) {
  json document = test::scene(drone(), 2.0);
  document["sources"][0]["level_db"] = 0;
  document["noise"] = {{"wind", {{"level_db", 80}}}};
  const RenderedArray array = render_array(parse_scenario(document, "."), 0);
  const auto a = channel(array, 0), b = channel(array, 1);
  EXPECT_GT(band_power(a, 0, 100), 100.0 * band_power(a, 1000, 24000));
  double ab = 0.0, aa = 0.0, bb = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    ab += a[i] * b[i], aa += a[i] * a[i], bb += b[i] * b[i];
  EXPECT_LT(std::abs(ab) / std::sqrt(aa * bb), 0.1);
}

TEST(Scene, AmbientIsCoherentAtLowFrequencyOnly) {
  json document = test::scene(drone(), 2.0);
  document["sources"][0]["level_db"] = 0;
  document["noise"] = {{"ambient", {{"level_db", 60}}}};
  const RenderedArray array = render_array(parse_scenario(document, "."), 0);
  auto coherence = [&](double low, double high) {
    const auto a = channel(array, 0), b = channel(array, 2);
    std::vector<double> sum(a.size()), difference(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) sum[i] = a[i] + b[i], difference[i] = a[i] - b[i];
    const double s = band_power(sum, low, high), d = band_power(difference, low, high);
    return (s - d) / (s + d);  // normalised cross-power
  };
  EXPECT_GT(coherence(20, 100), 0.8);
  EXPECT_LT(std::abs(coherence(2000, 4000)), 0.1);
}

TEST(Scene, LoudSceneIsScaledByOneCommonFactorWithAWarning) {
  json document = test::scene({{"id", "G"},
                               {"kind", "interferer"},
                               {"level_db", 135},
                               {"trajectory", {{"type", "hover"}, {"position_m", {2, 0, 1.5}}}}},
                              0.5);
  document["site"]["arrays"].push_back(
      {{"id", "A2"}, {"position_m", {50, 0, 1.5}}, {"mics_m", test::tetrahedron()}});
  const Scenario scenario = parse_scenario(document, ".");
  const RenderedArray raw_far = render_array(scenario, 1);
  testing::internal::CaptureStderr();
  const RenderedScene scene = render_scene(scenario);
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("would clip"), std::string::npos) << log;
  EXPECT_NE(log.find("all arrays scaled by"), std::string::npos) << log;
  ASSERT_GT(scene.peak_before_scaling, 1.0);
  EXPECT_NEAR(scene.scale, 0.9 / scene.peak_before_scaling, 1e-12);
  float peak = 0.0f;
  for (float value : scene.arrays[0].samples) peak = std::max(peak, std::abs(value));
  EXPECT_NEAR(peak, 0.9f, 1e-6f);
  // The far array got the same factor (levels between arrays stay true).
  for (std::size_t i = 0; i < raw_far.samples.size(); i += 997) {
    EXPECT_NEAR(scene.arrays[1].samples[i], raw_far.samples[i] * scene.scale, 1e-7);
  }
}

TEST(Scene, RenderingIsDeterministicAndIndependentOfWhichArraysAreRendered) {
  json document = test::scene(drone(), 0.5);
  document["site"]["arrays"].push_back(
      {{"id", "A2"}, {"position_m", {300, 0, 1.5}}, {"mics_m", test::tetrahedron()}});
  document["noise"] = {{"sensor", {{"snr_db", 10}}}, {"wind", {{"level_db", 60}}}};
  const Scenario scenario = parse_scenario(document, ".");
  const RenderedArray alone = render_array(scenario, 0);
  const RenderedScene scene = render_scene(scenario);
  // Equal up to float rounding (positions in the source buffer are relative to its start).
  ASSERT_EQ(alone.samples.size(), scene.arrays[0].samples.size());
  float largest = 0.0f, difference = 0.0f;
  for (std::size_t i = 0; i < alone.samples.size(); ++i) {
    largest = std::max(largest, std::abs(alone.samples[i]));
    difference = std::max(difference, std::abs(alone.samples[i] - scene.arrays[0].samples[i]));
  }
  EXPECT_LT(difference, 1e-5f * largest);
  EXPECT_EQ(render_array(scenario, 0).samples, alone.samples);  // bit-identical when repeated
  document["seed"] = 12;
  EXPECT_NE(render_array(parse_scenario(document, "."), 0).samples, alone.samples);
}

TEST(Scene, WritesReplayableSiteWavsAndTruth) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("sim_scene_test_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  json document = test::scene(drone(), 1.0);
  document["site"]["arrays"].push_back({{"id", "A2"},
                                        {"position_m", {20, 0, 1.5}},
                                        {"mics_m", test::tetrahedron()},
                                        {"recording_end_s", 0.6}});
  document["site"]["doa"] = {{"bands_hz", {{1500, 3500}}}};
  document["site"]["zones"] = {{{"name", "yard"}, {"polygon_m", {{0, 0}, {10, 0}, {10, 10}}}}};
  document["sources"].push_back({{"id", "G1"},
                                 {"kind", "interferer"},
                                 {"trajectory", {{"type", "hover"}, {"position_m", {5, 5, 0.5}}}}});
  const Scenario scenario = parse_scenario(document, ".");
  const WrittenScene written = write_scene(scenario, dir / "out");
  // The site loads with the site-config parser, recordings checked (exist, channels, rate).
  std::vector<std::string> warnings;
  const config::SiteConfig site = config::load_site_config(written.site, warnings);
  EXPECT_TRUE(warnings.empty());
  ASSERT_EQ(site.arrays.size(), 2u);
  EXPECT_EQ(site.arrays[1].recording, dir / "out" / "A2.wav");
  EXPECT_EQ(site.zones.size(), 1u);
  SF_INFO info{};
  SNDFILE* file = sf_open((dir / "out" / "A2.wav").c_str(), SFM_READ, &info);
  ASSERT_NE(file, nullptr);
  sf_close(file);
  EXPECT_EQ(info.frames, 28800);  // recording_end_s 0.6
  EXPECT_EQ(info.channels, 4);
  EXPECT_EQ(info.format, SF_FORMAT_WAV | SF_FORMAT_FLOAT);
  std::ifstream stream(written.truth);
  const json truth = json::parse(stream);
  ASSERT_EQ(truth["sources"].size(), 1u);  // drones only; interferers listed apart
  EXPECT_EQ(truth["interferers"][0]["id"], "G1");
  const json& d1 = truth["sources"][0];
  EXPECT_EQ(d1["id"], "D1");
  EXPECT_EQ(d1["t"].size(), 101u);
  EXPECT_EQ(d1["position_m"].size(), 101u);
  EXPECT_EQ(d1["velocity_mps"][0].size(), 3u);
  EXPECT_EQ(d1["doa"]["A2"]["direction"].size(), 101u);
  std::filesystem::remove_all(dir);
}

TEST(Scene, RealRecordingSourceKeepsExactPairDelays) {
  const std::filesystem::path recording = std::filesystem::path(DRONETRACK_SOURCE_DIR) /
                                          "../shared/data/drone-sounds/ddd_drone_017_ch0.wav";
  if (!std::filesystem::exists(recording)) GTEST_SKIP() << recording << " not present";
  const Eigen::Vector3d p(-14.0, 9.0, 11.0);
  json source = {{"id", "D1"},
                 {"level_db", 90},
                 {"signal", {{"type", "recording"}, {"file", recording.string()}, {"end_s", 8.2}}},
                 {"trajectory", {{"type", "hover"}, {"position_m", {p.x(), p.y(), p.z()}}}}};
  const Scenario scenario = parse_scenario(test::scene(source, 1.0), ".");
  const RenderedArray array = render_array(scenario, 0);
  const auto& geometry = scenario.site.arrays[0].geometry;
  for (std::size_t j = 1; j < 4; ++j) {
    const double expected_s =
        ((p - geometry.mic_site_m(0)).norm() - (p - geometry.mic_site_m(j)).norm()) / 343.0;
    const double measured_s =
        test::correlation_peak_lag(channel(array, 0, 4800), channel(array, j, 4800),
                                   expected_s * 48000.0, 3.0, 300.0, 12000.0) /
        48000.0;
    EXPECT_NEAR(measured_s, expected_s, 1e-6) << "pair 0-" << j;
  }
}

}  // namespace
}  // namespace dronetrack::sim::scene_test
