// Arrays as built (issue 16): the drawn errors are what the recordings hold. Each channel of a
// scene with array_errors against the same channel of the ideal scene: late by the node's clock
// plus the channel's delay, louder by the channel's gain; the mics where the draws put them; the
// same draws for the same seed and site; the reference log's fixes around the true path.
#include <cmath>
#include <sstream>

#include <gtest/gtest.h>

#include "sim/render.hpp"
#include "sim/scenario.hpp"
#include "tests/sim/sim_test_util.hpp"

namespace dronetrack::sim {
namespace {

using nlohmann::json;

json errors_scene() {
  // A broadband source 30 m out, no noise: every channel's delay is measurable to nanoseconds.
  json document = test::scene({{"id", "D1"},
                               {"level_db", 90},
                               {"signal", {{"type", "noise"}, {"low_hz", 300}, {"high_hz", 8000}}},
                               {"trajectory", {{"type", "hover"}, {"position_m", {20, 22, 8}}}}},
                              1.0);
  return document;
}

TEST(ArrayErrors, ChannelsRecordLateAndLoudAsDrawn) {
  json with_errors = errors_scene();
  with_errors["array_errors"] = {{"seed", 5},
                                 {"gain_spread_db", 1.0},
                                 {"channel_delay_std_s", 1e-4},
                                 {"clock_offset_std_s", 0.003}};
  const Scenario ideal = parse_scenario(errors_scene(), ".");
  const Scenario built = parse_scenario(with_errors, ".");
  const ArrayErrors& drawn = built.array_errors.at(0);
  EXPECT_NE(drawn.clock_offset_s, 0.0);
  const RenderedArray a = render_array(ideal, 0);
  const RenderedArray b = render_array(built, 0);
  for (std::size_t mic = 0; mic < 4; ++mic) {
    const auto clean = test::channel(a, mic, 4800, 43200);
    const auto late = test::channel(b, mic, 4800, 43200);
    const double expected_samples = drawn.recording_delay_s(mic) * 48000.0;
    const double lag =
        test::correlation_peak_lag(late, clean, expected_samples, 3.0, 300.0, 8000.0);
    EXPECT_NEAR(lag / 48000.0, drawn.recording_delay_s(mic), 2e-7) << "mic " << mic;
    double clean_power = 0.0, late_power = 0.0;
    for (std::size_t n = 0; n < clean.size(); ++n) {
      clean_power += clean[n] * clean[n];
      late_power += late[n] * late[n];
    }
    EXPECT_NEAR(10.0 * std::log10(late_power / clean_power), drawn.channel_gain_db[mic], 0.02)
        << "mic " << mic;
  }
}

// array_errors.channel_delays: one channel records exactly that late (one sample at 48 kHz),
// the others as they were; a bad entry is one error naming its path.
TEST(ArrayErrors, ChannelDelayAsSet) {
  const Scenario ideal = parse_scenario(errors_scene(), ".");
  const std::string id = ideal.site.arrays.at(0).geometry.id;
  json document = errors_scene();
  document["array_errors"] = {
      {"channel_delays", {{{"array", id}, {"channel", 2}, {"delay_s", 1.0 / 48000.0}}}}};
  const Scenario built = parse_scenario(document, ".");
  const RenderedArray a = render_array(ideal, 0);
  const RenderedArray b = render_array(built, 0);
  for (std::size_t mic = 0; mic < 4; ++mic) {
    const double expected_s = mic == 2 ? 1.0 / 48000.0 : 0.0;
    EXPECT_EQ(built.array_errors.at(0).channel_delay_s.at(mic), expected_s);
    const double lag = test::correlation_peak_lag(test::channel(b, mic, 4800, 43200),
                                                  test::channel(a, mic, 4800, 43200),
                                                  expected_s * 48000.0, 3.0, 300.0, 8000.0);
    EXPECT_NEAR(lag / 48000.0, expected_s, 2e-7) << "mic " << mic;
  }
  const std::vector<std::pair<json, std::string>> bad = {
      {{{"array", id}, {"channel", 4}, {"delay_s", 1e-4}},
       "array_errors.channel_delays[0].channel"},
      {{{"array", id}, {"channel", 1}}, "array_errors.channel_delays[0].delay_s"},
      {{{"array", id}, {"channel", 1}, {"delay_s", 0.5}}, "array_errors.channel_delays[0].delay_s"},
      {{{"array", "nowhere"}, {"channel", 1}, {"delay_s", 1e-4}},
       "array_errors.channel_delays[0].array"}};
  for (const auto& [entry, path] : bad) {
    document["array_errors"] = {{"channel_delays", {entry}}};
    try {
      parse_scenario(document, ".");
      ADD_FAILURE() << entry.dump();
    } catch (const config::ConfigError& error) {
      EXPECT_NE(std::string(error.what()).find(path), std::string::npos) << error.what();
    }
  }
}

TEST(ArrayErrors, MicsAndYawMoveAsDrawnAndTheDrawsFollowTheSeed) {
  json document = errors_scene();
  document["array_errors"] = {{"seed", 9}, {"mic_position_std_m", 0.003}, {"yaw_std_deg", 2.0}};
  const Scenario first = parse_scenario(document, ".");
  const Scenario again = parse_scenario(document, ".");
  const ArrayErrors& drawn = first.array_errors.at(0);
  // site.json keeps the nominal site; the rendered (true) geometry carries the draws.
  EXPECT_EQ(first.site_json["arrays"][0]["yaw_deg"].get<double>(), 30.0);
  EXPECT_DOUBLE_EQ(first.site.arrays[0].geometry.yaw_deg, 30.0 + drawn.yaw_deg);
  EXPECT_GT(std::abs(drawn.yaw_deg), 0.0);
  for (std::size_t mic = 0; mic < 4; ++mic) {
    const Eigen::Vector3d nominal(test::tetrahedron()[mic][0].get<double>(),
                                  test::tetrahedron()[mic][1].get<double>(),
                                  test::tetrahedron()[mic][2].get<double>());
    EXPECT_TRUE(first.site.arrays[0].geometry.mics_m[mic].isApprox(
        nominal + drawn.mic_offset_m[mic], 1e-12));
    EXPECT_EQ(again.array_errors[0].mic_offset_m[mic], drawn.mic_offset_m[mic]);
  }
  document["array_errors"]["seed"] = 10;
  EXPECT_NE(parse_scenario(document, ".").array_errors[0].yaw_deg, drawn.yaw_deg);
}

TEST(ArrayErrors, ReferenceLogFixesScatterAroundThePath) {
  json document = errors_scene();
  document["duration_s"] = 20.0;
  document["sources"][0]["trajectory"] = {
      {"type", "straight"}, {"start_m", {-40, 10, 12}}, {"velocity_mps", {4, 0, 0}}};
  document["reference_log"] = {{"source", "D1"}, {"rate_hz", 10}, {"position_std_m", 0.5}};
  const Scenario scenario = parse_scenario(document, ".");
  std::istringstream lines(reference_log_text(scenario));
  std::string line;
  int count = 0;
  double sum_squares = 0.0;
  while (std::getline(lines, line)) {
    const json fix = json::parse(line);
    const double t = fix["t"].get<double>();
    const Eigen::Vector3d truth = scenario.sources[0].trajectory.position(t);
    for (int k = 0; k < 3; ++k) {
      const double error = fix["position_m"][k].get<double>() - truth(k);
      sum_squares += error * error;
    }
    EXPECT_EQ(fix["position_std_m"].get<double>(), 0.5);
    ++count;
  }
  EXPECT_EQ(count, 201);  // 0 to 20 s at 10 Hz
  EXPECT_NEAR(std::sqrt(sum_squares / (3.0 * count)), 0.5, 0.05);
  document["reference_log"]["source"] = "D9";
  EXPECT_THROW(parse_scenario(document, "."), config::ConfigError);
}

}  // namespace
}  // namespace dronetrack::sim
