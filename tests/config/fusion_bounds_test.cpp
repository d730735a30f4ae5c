// The fusion's bounds, the one place they live (config/fusion_bounds.hpp): hand-made params get
// the lines the site config gives for the same values, naming the JSON path; the defaults pass.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "config/fusion_bounds.hpp"
#include "config/site_config.hpp"

namespace dronetrack::config::fusion_bounds_test {
namespace {

bool has(const std::vector<std::string>& problems, const std::string& line) {
  return std::find(problems.begin(), problems.end(), line) != problems.end();
}

std::string joined(const std::vector<std::string>& problems) {
  std::string all;
  for (const auto& problem : problems) all += "\n  " + problem;
  return all;
}

// The problems the site config gives for a "fusion" section.
std::vector<std::string> site_problems(const nlohmann::json& fusion) {
  const nlohmann::json array = {
      {"position_m", {0.0, 0.0, 1.5}},
      {"mics_m",
       {{0, 0, 0.5}, {0.471, 0, -0.167}, {-0.236, 0.408, -0.167}, {-0.236, -0.408, -0.167}}}};
  nlohmann::json a1 = array, a2 = array;
  a1["id"] = "A1";
  a2["id"] = "A2";
  a2["position_m"] = {20.0, 0.0, 1.5};
  const nlohmann::json site = {{"arrays", {a1, a2}}, {"fusion", fusion}};
  std::vector<std::string> warnings;
  LoadOptions options;
  options.check_recordings = false;
  try {
    parse_site_config(site.dump(), ".", warnings, options);
  } catch (const ConfigError& failure) {
    return failure.problems();
  }
  return {};
}

TEST(FusionBounds, DefaultsPass) {
  EXPECT_TRUE(fusion_params_problems(fusion::FusionParams{}).empty())
      << joined(fusion_params_problems(fusion::FusionParams{}));
  EXPECT_NO_THROW(validate(fusion::FusionParams{}));
}

TEST(FusionBounds, HandMadeParamsReadAsTheSiteConfigsKeys) {
  struct Case {
    void (*set)(fusion::FusionParams&);
    nlohmann::json section;
    std::string line;
  };
  const Case cases[] = {
      {[](fusion::FusionParams& p) { p.confirm_hits = 9; },
       {{"confirm_hits", 9}},
       "fusion.confirm_hits: must not exceed confirm_window"},
      {[](fusion::FusionParams& p) { p.confirm_hits = 2000; },
       {{"confirm_hits", 2000}},
       "fusion.confirm_hits: must be in [1, 1000], got 2000"},
      {[](fusion::FusionParams& p) { p.jerk_noise_std_mps3 = 0.0; },
       {{"jerk_noise_std_mps3", 0.0}},
       "fusion.jerk_noise_std_mps3: must be in [1e-06, 10000], got 0"},
      {[](fusion::FusionParams& p) { p.coast_after_s = 5.0; },
       {{"coast_after_s", 5.0}},
       "fusion.coast_after_s: must not exceed coast_timeout_s"},
      {[](fusion::FusionParams& p) {
         p.imm_turn_rate_std_radps2 = {1.0, 0.0};
       },
       {{"imm_turn_rate_std_radps2", {1.0, 0.0}}},
       "fusion.imm_turn_rate_std_radps2[1]: must be in (0, 1000]"},
      {[](fusion::FusionParams& p) { p.imm_jerk_std_mps3.assign(9, 1.0); },
       {{"imm_jerk_std_mps3", std::vector<double>(9, 1.0)}},
       "fusion.imm_jerk_std_mps3: at most 8 levels"},
      {[](fusion::FusionParams& p) { p.single_array.hypotheses_per_side = 65; },
       {{"single_array", {{"hypotheses_per_side", 65}}}},
       "fusion.single_array.hypotheses_per_side: must be in [1, 64], got 65"},
      {[](fusion::FusionParams& p) { p.single_array.source_plane_z_m = 2e4; },
       {{"source_plane_z_m", 2e4}},
       "fusion.source_plane_z_m: must be in [-10000, 10000], got 20000"},
      // Under the gate a rotation could pass for a mirror.
      {[](fusion::FusionParams& p) { p.mirror_check.min_separation_deg = 4.0; },
       {{"mirror_check", {{"min_separation_deg", 4.0}}}},
       "fusion.mirror_check.min_separation_deg: must exceed gate_deg"},
      {[](fusion::FusionParams& p) { p.mirror_check.evidence_ratio = 1.0; },
       {{"mirror_check", {{"evidence_ratio", 1.0}}}},
       "fusion.mirror_check.evidence_ratio: must be in [1.5, 10000], got 1"},
      {[](fusion::FusionParams& p) { p.classifier.drone_leave_share = 0.9; },
       {{"classifier", {{"drone_leave_share", 0.9}}}},
       "fusion.classifier.drone_leave_share: must not exceed drone_enter_share"},
      {[](fusion::FusionParams& p) { p.classifier.drone_max_fundamental_hz = 50.0; },
       {{"classifier", {{"drone_max_fundamental_hz", 50.0}}}},
       "fusion.classifier.drone_max_fundamental_hz: must exceed drone_min_fundamental_hz"},
  };
  for (const Case& c : cases) {
    fusion::FusionParams params;
    c.set(params);
    const auto by_hand = fusion_params_problems(params);
    EXPECT_EQ(by_hand, std::vector<std::string>{c.line}) << joined(by_hand);
    const auto from_json = site_problems(c.section);
    EXPECT_EQ(from_json, std::vector<std::string>{c.line}) << joined(from_json);
    try {
      validate(params);
      ADD_FAILURE() << "validate accepted " << c.line;
    } catch (const std::invalid_argument& error) {
      EXPECT_EQ(std::string(error.what()), c.line);
    }
  }
}

// A value no JSON can hold (the reader refuses non-finite numbers) is still out of bounds.
TEST(FusionBounds, NotANumberIsOutOfBounds) {
  fusion::FusionParams params;
  params.gate_probability = std::numeric_limits<double>::quiet_NaN();
  params.ground_altitude_m = std::numeric_limits<double>::infinity();
  const auto problems = fusion_params_problems(params);
  EXPECT_EQ(problems.size(), 2u) << joined(problems);
  EXPECT_TRUE(has(problems, "fusion.gate_probability: must be in [0.5, 0.999999], got nan"))
      << joined(problems);
}

TEST(FusionBounds, SpeedOfSoundIsBounded) {
  const nlohmann::json site = {{"speed_of_sound_mps", 0.0}, {"arrays", nlohmann::json::array()}};
  std::vector<std::string> warnings;
  try {
    parse_site_config(site.dump(), ".", warnings);
    ADD_FAILURE() << "accepted a speed of sound of 0";
  } catch (const ConfigError& failure) {
    EXPECT_TRUE(has(failure.problems(), "speed_of_sound_mps: must be in [100, 2000], got 0"))
        << joined(failure.problems());
  }
}

}  // namespace
}  // namespace dronetrack::config::fusion_bounds_test
