// Site config parsing and validation (SPEC 3.1): every validation error names its JSON path.
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sndfile.h>
#include <nlohmann/json.hpp>

#include "config/site_config.hpp"

namespace dronetrack::config::site_config_test {
namespace {

using nlohmann::json;

json tetra_array(const std::string& id, double x) {
  return {{"id", id},
          {"position_m", {x, 0.0, 1.5}},
          {"yaw_deg", 0.0},
          {"mics_m",
           {{0, 0, 0.5}, {0.471, 0, -0.167}, {-0.236, 0.408, -0.167}, {-0.236, -0.408, -0.167}}},
          {"recording", id + ".wav"}};
}

json two_array_site() {
  return {{"speed_of_sound_mps", 343.0},
          {"arrays", {tetra_array("A1", 0.0), tetra_array("A2", 20.0)}}};
}

LoadOptions no_recordings() {
  LoadOptions options;
  options.check_recordings = false;
  return options;
}

// Parses and expects failure; returns the problem lines.
std::vector<std::string> problems_of(const json& site, const LoadOptions& options = no_recordings(),
                                     const std::filesystem::path& base = ".") {
  std::vector<std::string> warnings;
  try {
    parse_site_config(site.dump(), base, warnings, options);
  } catch (const ConfigError& failure) {
    return failure.problems();
  }
  ADD_FAILURE() << "expected a ConfigError for " << site.dump();
  return {};
}

void expect_problem(const json& site, const std::string& expected,
                    const LoadOptions& options = no_recordings(),
                    const std::filesystem::path& base = ".") {
  const auto problems = problems_of(site, options, base);
  bool found = false;
  for (const auto& problem : problems) found = found || problem == expected;
  std::string all;
  for (const auto& problem : problems) all += "\n  " + problem;
  EXPECT_TRUE(found) << "expected \"" << expected << "\" among:" << all;
}

TEST(SiteConfig, ParsesTheSpecExampleWithDefaults) {
  std::vector<std::string> warnings;
  const SiteConfig site =
      parse_site_config(two_array_site().dump(), "/data/site", warnings, no_recordings());
  ASSERT_EQ(site.arrays.size(), 2u);
  EXPECT_TRUE(warnings.empty());
  EXPECT_DOUBLE_EQ(site.speed_of_sound_mps, 343.0);
  EXPECT_EQ(site.arrays[1].geometry.id, "A2");
  EXPECT_DOUBLE_EQ(site.arrays[1].geometry.position_m.x(), 20.0);
  EXPECT_EQ(site.arrays[0].geometry.mics_m.size(), 4u);
  EXPECT_EQ(site.arrays[0].recording, std::filesystem::path("/data/site/A1.wav"));
  EXPECT_EQ(site.arrays[0].channel_map, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(site.array_index("A2"), 1);
  EXPECT_EQ(site.array_index("nope"), -1);
  // Defaults for every processing parameter.
  EXPECT_DOUBLE_EQ(site.doa.bands_hz.at(0).low_hz, 1500.0);
  EXPECT_DOUBLE_EQ(site.doa.bands_hz.at(0).high_hz, 3500.0);
  EXPECT_TRUE(site.doa.per_band_detection);
  EXPECT_DOUBLE_EQ(site.fusion.output_rate_hz, 10.0);
  EXPECT_EQ(site.dds.domain_id, 0);
  EXPECT_EQ(site.http.bind, "127.0.0.1:8080");
}

TEST(SiteConfig, AbsoluteRecordingPathIsKept) {
  json site = two_array_site();
  site["arrays"][0]["recording"] = "/abs/A1.wav";
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_EQ(parsed.arrays[0].recording, std::filesystem::path("/abs/A1.wav"));
}

TEST(SiteConfig, MicWithTwoNumbersNamesItsPath) {
  json site = two_array_site();
  site["arrays"][1]["mics_m"][2] = {0.1, 0.2};
  expect_problem(site, "arrays[1].mics_m[2]: expected 3 numbers, got a list of 2");
}

TEST(SiteConfig, MissingKeys) {
  json site = two_array_site();
  site["arrays"][0].erase("position_m");
  site["arrays"][1].erase("id");
  const auto problems = problems_of(site);
  EXPECT_NE(std::find(problems.begin(), problems.end(),
                      "arrays[0].position_m: required [x, y, z] is missing"),
            problems.end());
  EXPECT_NE(std::find(problems.begin(), problems.end(), "arrays[1].id: required string is missing"),
            problems.end());
  expect_problem(json{{"speed_of_sound_mps", 343}}, "arrays: required list is missing");
  json no_mics = two_array_site();
  no_mics["arrays"][0].erase("mics_m");
  expect_problem(no_mics, "arrays[0].mics_m: required list of mic positions is missing");
}

TEST(SiteConfig, WrongTypes) {
  json site = two_array_site();
  site["speed_of_sound_mps"] = "fast";
  expect_problem(site, "speed_of_sound_mps: expected a number, got a string");
  json arrays_not_list = two_array_site();
  arrays_not_list["arrays"] = json::object();
  expect_problem(arrays_not_list, "arrays: expected a list, got an object");
  json mic_string = two_array_site();
  mic_string["arrays"][0]["mics_m"][1][0] = "x";
  expect_problem(mic_string, "arrays[0].mics_m[1][0]: expected a number, got a string");
  expect_problem(json::array(), "(top level): expected an object, got a list of 0");
}

TEST(SiteConfig, NonFiniteNumbersAreRejected) {
  // JSON has no NaN literal; the only way to write a non-finite number is an overflowing one.
  std::string text = two_array_site().dump();
  const std::string needle = "\"yaw_deg\":0.0";
  ASSERT_NE(text.find(needle), std::string::npos);
  text.replace(text.find(needle), needle.size(), "\"yaw_deg\":1e999");
  std::vector<std::string> warnings;
  try {
    parse_site_config(text, ".", warnings, no_recordings());
    FAIL() << "expected an error";
  } catch (const ConfigError& failure) {
    ASSERT_EQ(failure.problems().size(), 1u);
    EXPECT_NE(failure.problems()[0].find("number overflow"), std::string::npos)
        << failure.problems()[0];
  }
}

TEST(SiteConfig, OutOfRangeValues) {
  json site = two_array_site();
  site["speed_of_sound_mps"] = -5;
  expect_problem(site, "speed_of_sound_mps: must be in [100, 2000], got -5");
}

TEST(SiteConfig, DuplicateArrayIds) {
  json site = two_array_site();
  site["arrays"][1]["id"] = "A1";
  expect_problem(site, "arrays[1].id: duplicate array id \"A1\"");
}

TEST(SiteConfig, ArrayIdsArePlain) {
  json site = two_array_site();
  site["arrays"][0]["id"] = "A \"1\"";
  expect_problem(site, "arrays[0].id: \"A \"1\"\": use only letters, digits, '_', '-' or '.'");
}

TEST(SiteConfig, FewerThanTwoMics) {
  json site = two_array_site();
  site["arrays"][0]["mics_m"] = {{0, 0, 0}};
  expect_problem(site, "arrays[0].mics_m: an array needs at least 2 mics, got 1");
}

TEST(SiteConfig, CoincidentMics) {
  json site = two_array_site();
  site["arrays"][0]["mics_m"][3] = {0, 0, 0.5};
  expect_problem(site, "arrays[0].mics_m: mics 0 and 3 coincide (closer than 1 mm)");
}

TEST(SiteConfig, UnknownKeysWarnButParse) {
  json site = two_array_site();
  site["colour"] = "blue";
  site["arrays"][0]["height"] = 3;
  site["doa"] = {{"frame_s", 0.2}, {"hop", 0.2}};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), ".", warnings, no_recordings());
  EXPECT_DOUBLE_EQ(parsed.doa.frame_s, 0.2);
  EXPECT_NE(std::find(warnings.begin(), warnings.end(), "colour: unknown key, ignored"),
            warnings.end());
  EXPECT_NE(std::find(warnings.begin(), warnings.end(), "arrays[0].height: unknown key, ignored"),
            warnings.end());
  EXPECT_NE(std::find(warnings.begin(), warnings.end(), "doa.hop: unknown key, ignored"),
            warnings.end());
}

TEST(SiteConfig, ProcessingSectionsValidated) {
  json site = two_array_site();
  site["doa"] = {{"tdoa_tracker", "magic"},
                 {"bands_hz", {{3000, 1000}}},
                 {"snr_weight_floor", 1.5},
                 {"snr_weighting", "yes"},
                 {"ground_echo", 1},
                 {"ground_height_m", "low"},
                 {"static_null_cancel_min_residual_over_noise", -1}};
  site["fusion"] = {{"confirm_hits", 9}, {"confirm_window", 4}};
  const auto problems = problems_of(site);
  auto has = [&](const std::string& line) {
    return std::find(problems.begin(), problems.end(), line) != problems.end();
  };
  EXPECT_TRUE(has("doa.bands_hz[0]: expected 0 <= low_hz < high_hz"));
  EXPECT_TRUE(has("doa.snr_weight_floor: must be in [0, 1], got 1.5"));
  EXPECT_TRUE(has("doa.snr_weighting: expected true or false, got a string"));
  EXPECT_TRUE(has("doa.ground_echo: expected true or false, got a number"));
  EXPECT_TRUE(has("doa.ground_height_m: expected a number, got a string"));
  EXPECT_TRUE(has("doa.static_null_cancel_min_residual_over_noise: must be in [0, 1000], got -1"));
  EXPECT_TRUE(
      has("doa.tdoa_tracker: unknown value \"magic\", expected one of: per_frame, "
          "bayesian_grid, multi_peak, robust_regression"));
  EXPECT_TRUE(has("fusion.confirm_hits: must not exceed confirm_window"));
}

TEST(SiteConfig, StaticCancelResidualRuleKey) {
  json site = two_array_site();
  std::vector<std::string> warnings;
  EXPECT_DOUBLE_EQ(parse_site_config(site.dump(), ".", warnings, no_recordings())
                       .doa.static_null_cancel_min_residual_over_noise,
                   2.0);
  site["doa"] = {{"static_null_cancel_min_residual_over_noise", 0.5}};
  EXPECT_DOUBLE_EQ(parse_site_config(site.dump(), ".", warnings, no_recordings())
                       .doa.static_null_cancel_min_residual_over_noise,
                   0.5);
}

TEST(SiteConfig, PerBandDetectionKey) {
  json site = two_array_site();
  site["doa"] = {{"bands_hz", {{1000, 3000}, {4000, 6000}}}, {"per_band_detection", false}};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_FALSE(parsed.doa.per_band_detection);
  EXPECT_TRUE(warnings.empty());
  EXPECT_EQ(parsed.doa.bands_hz.size(), 2U);
  site["doa"]["per_band_detection"] = "yes";
  expect_problem(site, "doa.per_band_detection: expected true or false, got a string");
}

TEST(SiteConfig, StaticLookSection) {
  json site = two_array_site();
  site["doa"] = {{"static_look",
                  {{"enabled", false},
                   {"averaging_time_s", 0.3},
                   {"max_drift_deg", 0.5},
                   {"hold_s", 2.0},
                   {"min_elevation_deg", 8.0},
                   {"own_look_memory_s", 0.0}}}};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_TRUE(warnings.empty());
  EXPECT_FALSE(parsed.doa.static_look.enabled);
  EXPECT_DOUBLE_EQ(parsed.doa.static_look.averaging_time_s, 0.3);
  EXPECT_DOUBLE_EQ(parsed.doa.static_look.max_drift_deg, 0.5);
  EXPECT_DOUBLE_EQ(parsed.doa.static_look.hold_s, 2.0);
  EXPECT_DOUBLE_EQ(parsed.doa.static_look.min_elevation_deg, 8.0);
  EXPECT_DOUBLE_EQ(parsed.doa.static_look.own_look_memory_s, 0.0);
  EXPECT_TRUE(parse_site_config(two_array_site().dump(), "/data", warnings, no_recordings())
                  .doa.static_look.enabled);  // on unless turned off
  site["doa"]["static_look"]["averaging_time_s"] = 0.0;
  expect_problem(site, "doa.static_look.averaging_time_s: must be in [0.01, 10], got 0");
  site["doa"]["static_look"]["averaging_time_s"] = 0.3;
  site["doa"]["static_look"]["enabled"] = "on";
  expect_problem(site, "doa.static_look.enabled: expected true or false, got a string");
}

// doa.follow_source_tracks: off by default, on when the site says so, a boolean or a problem.
TEST(SiteConfig, FollowSourceTracksIsOffUnlessTurnedOn) {
  std::vector<std::string> warnings;
  EXPECT_FALSE(parse_site_config(two_array_site().dump(), "/data", warnings, no_recordings())
                   .doa.follow_source_tracks);
  json site = two_array_site();
  site["doa"] = {{"follow_source_tracks", true}};
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_TRUE(warnings.empty());
  EXPECT_TRUE(parsed.doa.follow_source_tracks);
  site["doa"]["follow_source_tracks"] = 1;
  expect_problem(site, "doa.follow_source_tracks: expected true or false, got a number");
}

// doa.free_look_lobe_choice: off by default, on when the site says so, a boolean or a problem.
TEST(SiteConfig, FreeLookLobeChoiceIsOffUnlessTurnedOn) {
  std::vector<std::string> warnings;
  EXPECT_FALSE(parse_site_config(two_array_site().dump(), "/data", warnings, no_recordings())
                   .doa.free_look_lobe_choice);
  json site = two_array_site();
  site["doa"] = {{"free_look_lobe_choice", true}};
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_TRUE(warnings.empty());
  EXPECT_TRUE(parsed.doa.free_look_lobe_choice);
  site["doa"]["free_look_lobe_choice"] = "yes";
  expect_problem(site, "doa.free_look_lobe_choice: expected true or false, got a string");
}

// doa.comb_look: on by default, off when the site says so, a boolean or a problem.
TEST(SiteConfig, CombLookIsOnUnlessTurnedOff) {
  std::vector<std::string> warnings;
  EXPECT_TRUE(
      parse_site_config(two_array_site().dump(), "/data", warnings, no_recordings()).doa.comb_look);
  json site = two_array_site();
  site["doa"] = {{"comb_look", false}};
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_TRUE(warnings.empty());
  EXPECT_FALSE(parsed.doa.comb_look);
  site["doa"]["comb_look"] = 1;
  expect_problem(site, "doa.comb_look: expected true or false, got a number");
}

TEST(SiteConfig, GroundMustBeUnderEveryMicForTheEchoModel) {
  json site = two_array_site();
  site["doa"] = {{"ground_height_m", 1.4}};
  // The tetrahedra's three lower mics sit at z 1.5 - 0.167 = 1.333 m.
  expect_problem(site,
                 "arrays[0].mics_m[1]: mic at site z 1.333 m is not above the ground "
                 "(doa.ground_height_m 1.4); raise it, or set doa.ground_echo false");
  site["doa"]["ground_echo"] = false;
  std::vector<std::string> warnings;
  EXPECT_FALSE(parse_site_config(site.dump(), ".", warnings, no_recordings()).doa.ground_echo);
}

TEST(SiteConfig, TwoMicAndPlanarArraysNeedNoGroundUnderThem) {
  // Only 3-D arrays model the ground echo: a hydrophone pair (a cone) or a planar array below
  // the ground height is accepted beside a tetrahedron, which still must stand above it.
  json site = two_array_site();
  site["arrays"][1]["mics_m"] = {{-0.3, 0.0, 0.0}, {0.3, 0.0, 0.0}};
  site["arrays"][1]["position_m"] = {20.0, 0.0, -5.0};
  site["arrays"].push_back(tetra_array("A3", 40.0));
  site["arrays"][2]["mics_m"] = {{0.3, 0.0, 0.0}, {-0.15, 0.26, 0.0}, {-0.15, -0.26, 0.0}};
  site["arrays"][2]["position_m"] = {40.0, 0.0, -2.0};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), ".", warnings, no_recordings());
  ASSERT_EQ(parsed.arrays.size(), 3U);
  EXPECT_EQ(parsed.arrays[1].geometry.mic_count(), 2U);
  EXPECT_TRUE(parsed.doa.ground_echo);
  site["arrays"][0]["position_m"] = {0.0, 0.0, -5.0};
  expect_problem(site,
                 "arrays[0].mics_m[0]: mic at site z -4.5 m is not above the ground "
                 "(doa.ground_height_m 0); raise it, or set doa.ground_echo false");
}

TEST(SiteConfig, AnArrayMayStandOnItsOwnGround) {
  json site = two_array_site();
  site["doa"] = {{"ground_height_m", 0.5}};
  site["arrays"][1]["position_m"] = {20.0, 0.0, 11.5};  // on a 10 m rise
  site["arrays"][1]["ground_height_m"] = 10.0;
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), ".", warnings, no_recordings());
  EXPECT_EQ(parsed.doa_params(0).ground_height_m, 0.5);
  EXPECT_EQ(parsed.doa_params(1).ground_height_m, 10.0);
  site["arrays"][1]["ground_height_m"] = 11.4;
  expect_problem(site,
                 "arrays[1].mics_m[1]: mic at site z 11.333 m is not above the ground "
                 "(arrays[1].ground_height_m 11.4); raise it, or set doa.ground_echo false");
}

TEST(SiteConfig, TurnModeKeysParseAndValidate) {
  json site = two_array_site();
  site["fusion"] = {{"imm_turn_mode", true},
                    {"imm_turn_rate_std_radps2", {0.5, 20}},
                    {"imm_turn_jerk_std_mps3", 0.2}};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), ".", warnings, no_recordings());
  EXPECT_TRUE(parsed.fusion.imm_turn_mode);
  EXPECT_EQ(parsed.fusion.imm_turn_rate_std_radps2, (std::vector<double>{0.5, 20}));
  EXPECT_DOUBLE_EQ(parsed.fusion.imm_turn_jerk_std_mps3, 0.2);
  site["fusion"]["imm_turn_rate_std_radps2"] = {1, -2};
  expect_problem(site, "fusion.imm_turn_rate_std_radps2[1]: must be in (0, 1000]");
}

TEST(SiteConfig, ZonesParseAndValidate) {
  json site = two_array_site();
  site["zones"] = {
      {{"name", "yard"}, {"polygon_m", {{0, 0}, {10, 0}, {10, 10}}}, {"altitude_m", {0, 50}}},
      {{"name", "bad"}, {"polygon_m", {{0, 0}, {1, 1}}}}};
  expect_problem(site, "zones[1].polygon_m: a zone needs at least 3 vertices");
  site["zones"].erase(1);
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), ".", warnings, no_recordings());
  ASSERT_EQ(parsed.zones.size(), 1u);
  EXPECT_EQ(parsed.zones[0].polygon_m.size(), 3u);
  EXPECT_DOUBLE_EQ(parsed.zones[0].altitude_max_m, 50.0);
}

TEST(SiteConfig, InvalidJsonIsOneLine) {
  std::vector<std::string> warnings;
  try {
    parse_site_config("{\"arrays\": [", ".", warnings, no_recordings());
    FAIL();
  } catch (const ConfigError& failure) {
    ASSERT_EQ(failure.problems().size(), 1u);
    EXPECT_EQ(failure.problems()[0].rfind("invalid JSON: ", 0), 0u);
  }
}

TEST(SiteConfig, ChannelMapValidated) {
  json site = two_array_site();
  site["arrays"][0]["channel_map"] = {3, 2, 1};
  expect_problem(site, "arrays[0].channel_map: has 3 entries for 4 mics");
  site["arrays"][0]["channel_map"] = {0, 1, 1, 2};
  expect_problem(site, "arrays[0].channel_map[2]: channel 1 is mapped twice");
}

class SiteWithRecordings : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("dronetrack_config_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  void write_wav(const std::string& name, int channels, int rate) {
    SF_INFO info{};
    info.channels = channels;
    info.samplerate = rate;
    info.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
    SNDFILE* file = sf_open((dir_ / name).c_str(), SFM_WRITE, &info);
    ASSERT_NE(file, nullptr);
    std::vector<float> samples(static_cast<std::size_t>(channels) * 100, 0.0f);
    sf_writef_float(file, samples.data(), 100);
    sf_close(file);
  }
  std::filesystem::path dir_;
};

TEST_F(SiteWithRecordings, ChannelCountMustMatchMics) {
  write_wav("A1.wav", 4, 48000);
  write_wav("A2.wav", 3, 48000);
  const auto wav = (dir_ / "A2.wav").string();
  expect_problem(two_array_site(),
                 "arrays[1].recording: " + wav + " has 3 channels but the array has 4 mics",
                 LoadOptions{}, dir_);
}

TEST_F(SiteWithRecordings, MissingRecording) {
  write_wav("A1.wav", 4, 48000);
  expect_problem(two_array_site(),
                 "arrays[1].recording: " + (dir_ / "A2.wav").string() + ": recording not found",
                 LoadOptions{}, dir_);
}

TEST_F(SiteWithRecordings, NyquistBelowBand) {
  write_wav("A1.wav", 4, 48000);
  write_wav("A2.wav", 4, 6000);
  expect_problem(
      two_array_site(),
      "arrays[1].recording: " + (dir_ / "A2.wav").string() +
          ": sample rate 6000 Hz puts the Nyquist frequency below the band's upper edge (3500 Hz)",
      LoadOptions{}, dir_);
}

TEST_F(SiteWithRecordings, ChannelMapSelectsChannelsOfAWiderRecording) {
  write_wav("A1.wav", 6, 48000);
  write_wav("A2.wav", 4, 48000);
  json site = two_array_site();
  site["arrays"][0]["channel_map"] = {5, 4, 3, 2};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), dir_, warnings, LoadOptions{});
  EXPECT_EQ(parsed.arrays[0].channel_map, (std::vector<int>{5, 4, 3, 2}));
  site["arrays"][0]["channel_map"] = {6, 4, 3, 2};
  expect_problem(site,
                 "arrays[0].channel_map[0]: channel 6 does not exist in " +
                     (dir_ / "A1.wav").string() + " (6 channels)",
                 LoadOptions{}, dir_);
}

TEST_F(SiteWithRecordings, LoadPrefixesTheFileName) {
  const auto file = dir_ / "site.json";
  std::ofstream(file)
      << R"({"arrays": [{"id": "A1", "position_m": [0, 0], "mics_m": [[0,0,0],[1,0,0]]}]})";
  std::vector<std::string> warnings;
  try {
    load_site_config(file, warnings, no_recordings());
    FAIL();
  } catch (const ConfigError& failure) {
    EXPECT_EQ(failure.problems().at(0),
              file.string() + ": arrays[0].position_m: expected 3 numbers, got a list of 2");
  }
}

// Issue 16: the fusion's swap check (fusion.mirror_check), keys with units and their bounds.
TEST(SiteConfig, MirrorCheckKeys) {
  json site = two_array_site();
  site["fusion"] = {{"mirror_check", {{"gate_deg", 4}, {"evidence_ratio", 8}, {"enabled", false}}}};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_EQ(parsed.fusion.mirror_check.gate_deg, 4.0);
  EXPECT_EQ(parsed.fusion.mirror_check.evidence_ratio, 8.0);
  EXPECT_FALSE(parsed.fusion.mirror_check.enabled);
  EXPECT_EQ(parsed.fusion.mirror_check.min_separation_deg, 20.0);  // the default
  site["fusion"] = {{"mirror_check", {{"gate_deg", 10}, {"min_separation_deg", 8}}}};
  expect_problem(site, "fusion.mirror_check.min_separation_deg: must exceed gate_deg");
  site["fusion"] = {{"mirror_check", {{"evidence_ratio", 1}}}};
  expect_problem(site, "fusion.mirror_check.evidence_ratio: must be in [1.5, 10000], got 1");
}

TEST(SiteConfig, DoaLikelihoodIsChosenByName) {
  json site = two_array_site();
  site["fusion"] = {{"likelihood", "student_t"}, {"student_t_dof", 6}};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_EQ(parsed.fusion.likelihood, fusion::DoaLikelihoodKind::student_t);
  EXPECT_EQ(parsed.fusion.student_t_dof, 6.0);
  const SiteConfig defaults =
      parse_site_config(two_array_site().dump(), "/data", warnings, no_recordings());
  EXPECT_EQ(defaults.fusion.likelihood, fusion::DoaLikelihoodKind::outlier_mixture);
  EXPECT_EQ(defaults.fusion.outlier_probability, 0.1);
  site["fusion"] = {{"likelihood", "gaussian"}};
  EXPECT_EQ(parse_site_config(site.dump(), "/data", warnings, no_recordings()).fusion.likelihood,
            fusion::DoaLikelihoodKind::gaussian);
  site["fusion"] = {{"likelihood", "outlier_mixture"}, {"outlier_probability", 0.3}};
  const SiteConfig chosen = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_EQ(chosen.fusion.likelihood, fusion::DoaLikelihoodKind::outlier_mixture);
  EXPECT_EQ(chosen.fusion.outlier_probability, 0.3);
  site["fusion"] = {{"likelihood", "cauchy"}};
  const auto problems = problems_of(site);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("fusion.likelihood"), std::string::npos) << problems[0];
  site["fusion"] = {{"student_t_dof", 0.5}};
  expect_problem(site, "fusion.student_t_dof: must be in [1, 100], got 0.5");
  site["fusion"] = {{"outlier_probability", 0.95}};
  expect_problem(site, "fusion.outlier_probability: must be in [0, 0.9], got 0.95");
  // e estimated per array (off by default): window and prior strength in DOAs.
  EXPECT_FALSE(defaults.fusion.adaptive_outlier_probability);
  site["fusion"] = {{"adaptive_outlier_probability", true},
                    {"outlier_window_doas", 800},
                    {"outlier_prior_doas", 20}};
  const SiteConfig adaptive = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_TRUE(adaptive.fusion.adaptive_outlier_probability);
  EXPECT_EQ(adaptive.fusion.outlier_window_doas, 800);
  EXPECT_EQ(adaptive.fusion.outlier_prior_doas, 20.0);
  site["fusion"] = {{"outlier_window_doas", 10}};
  expect_problem(site, "fusion.outlier_window_doas: must be in [50, 100000], got 10");
  site["fusion"] = {{"outlier_prior_doas", -1}};
  expect_problem(site, "fusion.outlier_prior_doas: must be in [0, 100000], got -1");
  // outlier_spread_deg was tried and removed (docs/fusion.md "Where the outliers land"): a site
  // that still sets it is told the key is ignored.
  site["fusion"] = {{"outlier_spread_deg", 30}};
  warnings.clear();
  parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_NE(std::find(warnings.begin(), warnings.end(),
                      "fusion.outlier_spread_deg: unknown key, ignored"),
            warnings.end());
}

}  // namespace
// Issue 15's fusion keys: the one-array localisers and the source plane.
TEST(SiteConfig, OneArrayLocalisersAreConfigured) {
  json site = two_array_site();
  site["fusion"] = {{"single_array_start", true},
                    {"single_array_filter", "particle_multipeak"},
                    {"source_plane_z_m", -4.5},
                    {"single_array",
                     {{"hypothesis_spacing_m", 50},
                      {"hypotheses_per_side", 10},
                      {"max_range_m", 600},
                      {"hypothesis_range_ratio", 1.5},
                      {"own_spread_weights", true},
                      {"range_init_m", 30}}}};
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_TRUE(parsed.fusion.single_array_start);
  EXPECT_EQ(parsed.fusion.single_array_filter, fusion::FilterKind::particle_multipeak);
  ASSERT_TRUE(parsed.fusion.single_array.source_plane_z_m.has_value());
  EXPECT_EQ(*parsed.fusion.single_array.source_plane_z_m, -4.5);
  EXPECT_EQ(parsed.fusion.single_array.hypothesis_spacing_m, 50.0);
  EXPECT_EQ(parsed.fusion.single_array.hypotheses_per_side, 10);
  EXPECT_EQ(parsed.fusion.single_array.max_range_m, 600.0);
  EXPECT_EQ(parsed.fusion.single_array.hypothesis_range_ratio, 1.5);
  EXPECT_TRUE(parsed.fusion.single_array.own_spread_weights);
  EXPECT_EQ(parsed.fusion.single_array.range_init_m, 30.0);
  EXPECT_EQ(parsed.fusion.single_array.prune_gamma, 0.1);  // default kept
  const SiteConfig plain =
      parse_site_config(two_array_site().dump(), "/data", warnings, no_recordings());
  EXPECT_FALSE(plain.fusion.single_array_start);
  EXPECT_FALSE(plain.fusion.single_array.source_plane_z_m.has_value());
  site["fusion"] = {{"single_array_filter", "ukf"}};
  const auto problems = problems_of(site);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("fusion.single_array_filter"), std::string::npos) << problems[0];
  // The static-source prior docs/fusion.md gives ("Static sources") is accepted.
  site["fusion"] = {
      {"single_array",
       {{"velocity_std_mps", 0.01}, {"acceleration_std_mps2", 1e-4}, {"jerk_std_mps3", 1e-5}}}};
  const SiteConfig static_prior =
      parse_site_config(site.dump(), "/data", warnings, no_recordings());
  EXPECT_EQ(static_prior.fusion.single_array.velocity_std_mps, 0.01);
  EXPECT_EQ(static_prior.fusion.single_array.acceleration_std_mps2, 1e-4);
  EXPECT_EQ(static_prior.fusion.single_array.jerk_std_mps3, 1e-5);
  site["fusion"] = {{"single_array", {{"acceleration_std_mps2", 1e-7}}}};
  expect_problem(site,
                 "fusion.single_array.acceleration_std_mps2: must be in [1e-06, 1000], got 1e-07");
  site["fusion"] = {{"single_array", {{"hypotheses_per_side", 0}}}};
  expect_problem(site, "fusion.single_array.hypotheses_per_side: must be in [1, 64], got 0");
  // A site of one array feeds a fusion only when it may start tracks from one array.
  LoadOptions fusion_options = no_recordings();
  fusion_options.for_fusion = true;
  json one_array = {{"arrays", {tetra_array("A1", 0.0)}}};
  expect_problem(one_array,
                 "arrays: the fusion needs at least 2 arrays (it triangulates), got 1 (or "
                 "fusion.single_array_start: true)",
                 fusion_options);
  one_array["fusion"] = {{"single_array_start", true}};
  EXPECT_EQ(parse_site_config(one_array.dump(), "/data", warnings, fusion_options).arrays.size(),
            1u);
}

}  // namespace dronetrack::config::site_config_test

namespace dronetrack::config::site_config_test {
namespace {

// A site calibration's keys (docs/calibration.md): read per mic, bounded, named when wrong.
TEST(SiteConfig, CalibrationKeys) {
  json site = two_array_site();
  site["arrays"][1]["channel_delay_s"] = {0.0, 1e-4, -2e-5, 3e-5};
  site["arrays"][1]["channel_gain_db"] = {0.0, 0.8, -1.1, 0.2};
  site["arrays"][1]["clock_offset_s"] = 0.005;
  std::vector<std::string> warnings;
  const SiteConfig parsed = parse_site_config(site.dump(), ".", warnings, no_recordings());
  EXPECT_TRUE(warnings.empty());
  EXPECT_TRUE(parsed.arrays[0].geometry.channel_delay_s.empty());
  EXPECT_EQ(parsed.arrays[1].geometry.channel_delay_s,
            (std::vector<double>{0.0, 1e-4, -2e-5, 3e-5}));
  EXPECT_EQ(parsed.arrays[1].geometry.channel_gain_db, (std::vector<double>{0.0, 0.8, -1.1, 0.2}));
  EXPECT_DOUBLE_EQ(parsed.arrays[1].geometry.clock_offset_s, 0.005);

  site["arrays"][1]["channel_delay_s"] = {0.0, 1e-4};
  expect_problem(site, "arrays[1].channel_delay_s: has 2 entries for 4 mics");
  site["arrays"][1]["channel_delay_s"] = {0.0, 0.0, 0.0, 0.5};
  expect_problem(site, "arrays[1].channel_delay_s[3]: must be within +-0.1, got 0.5");
}

}  // namespace
}  // namespace dronetrack::config::site_config_test

namespace dronetrack::config::site_config_test {
namespace {

TEST(SiteConfig, IncidentCaptureKeys) {
  json site = two_array_site();
  std::vector<std::string> warnings;
  EXPECT_FALSE(
      parse_site_config(site.dump(), "/site", warnings, no_recordings()).incident.enabled());
  site["incident"] = {
      {"directory", "incidents"}, {"ring_s", 120}, {"before_s", 20}, {"after_s", 10}};
  const SiteConfig parsed = parse_site_config(site.dump(), "/site", warnings, no_recordings());
  EXPECT_EQ(parsed.incident.directory, std::filesystem::path("/site/incidents"));
  EXPECT_DOUBLE_EQ(parsed.incident.ring_s, 120.0);
  EXPECT_DOUBLE_EQ(parsed.incident.before_s, 20.0);
  EXPECT_DOUBLE_EQ(parsed.incident.after_s, 10.0);
  site["incident"]["ring_s"] = 35;
  expect_problem(site,
                 "incident.ring_s: 35 s cannot hold a clip of before_s + after_s = 30 s and the "
                 "alert's delay (10 s); make it at least 40");
  site["incident"]["ring_s"] = 120;
  site["incident"]["after_s"] = -1;
  expect_problem(site, "incident.after_s: must be in [0, 3600], got -1");
  site["incident"]["after_s"] = 10;
  site["incident"]["directory"] = "";
  expect_problem(site, "incident.directory: must not be empty");
}

}  // namespace
}  // namespace dronetrack::config::site_config_test
