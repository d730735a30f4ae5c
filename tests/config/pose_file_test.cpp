// A moving array's pose file (issue 15): read at config load into the array's PoseTrack, and
// every bad file gives one problem naming FILE:LINE (non-monotonic or repeated t, NaN, missing
// keys, a gap, a turn too fast for the pose rate, absurd coordinates, too few or too long lines).
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "config/pose_file.hpp"
#include "config/site_config.hpp"

namespace dronetrack::config::pose_file_test {
namespace {

using nlohmann::json;

class PoseFileConfig : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("dronetrack_pose_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  void write(const std::string& text) { std::ofstream(dir_ / "pose.jsonl") << text; }
  std::string file() const { return (dir_ / "pose.jsonl").string(); }

  static json site(json extra = json::object()) {
    json array = {{"id", "M1"},
                  {"position_m", {0.0, 0.0, 1.5}},
                  {"mics_m", {{-0.5, 0, 0}, {0.5, 0, 0}}},
                  {"pose_file", "pose.jsonl"}};
    array.update(extra);
    return {{"arrays", {array}}};
  }
  SiteConfig parse(const json& document) {
    std::vector<std::string> warnings;
    LoadOptions options;
    options.check_recordings = false;
    return parse_site_config(document.dump(), dir_, warnings, options);
  }
  // The one problem a bad pose file gives.
  std::string problem(const json& document = site()) {
    try {
      parse(document);
    } catch (const ConfigError& failure) {
      EXPECT_EQ(failure.problems().size(), 1U);
      return failure.problems().at(0);
    }
    ADD_FAILURE() << "expected a ConfigError";
    return "";
  }
  std::filesystem::path dir_;
};

TEST_F(PoseFileConfig, ReadsLinesIntoTheArraysPoseTrack) {
  write(R"({"t": 0.0, "position_m": [0, 0, 1.5], "yaw_deg": 170}
{"t": 0.5, "position_m": [1, 0, 1.5], "yaw_deg": -170, "pitch_deg": 2.5, "roll_deg": -1, "speed_mps": 2}

{"t": 1.0, "position_m": [2, 0, 1.5], "yaw_deg": -150}
)");
  const SiteConfig config = parse(site({{"pitch_deg", 5.0}, {"roll_deg", -3.0}}));
  const ArrayConfig& array = config.arrays.at(0);
  EXPECT_EQ(array.pose_file, dir_ / "pose.jsonl");
  EXPECT_TRUE(array.moving());
  ASSERT_EQ(array.pose.samples().size(), 3U);
  EXPECT_DOUBLE_EQ(array.pose.samples()[1].yaw_deg, -170.0);
  EXPECT_DOUBLE_EQ(array.pose.samples()[1].pitch_deg, 2.5);
  EXPECT_DOUBLE_EQ(array.pose.samples()[1].roll_deg, -1.0);
  EXPECT_DOUBLE_EQ(array.pose.samples()[0].pitch_deg, 0.0);
  EXPECT_DOUBLE_EQ(array.pose.samples()[2].position_m.x(), 2.0);
  EXPECT_DOUBLE_EQ(array.pose.end_s(), 1.0);
  EXPECT_DOUBLE_EQ(array.geometry.pitch_deg, 5.0);
  EXPECT_DOUBLE_EQ(array.geometry.roll_deg, -3.0);
  EXPECT_DOUBLE_EQ(array.pose_max_gap_s, 1.0);
  EXPECT_FALSE(array.pose_topic);
}

TEST_F(PoseFileConfig, FixedArrayHasNoPose) {
  json document = site();
  document["arrays"][0].erase("pose_file");
  const SiteConfig config = parse(document);
  EXPECT_FALSE(config.arrays[0].moving());
  document["arrays"][0]["pose_topic"] = true;
  EXPECT_TRUE(parse(document).arrays[0].moving());
}

TEST_F(PoseFileConfig, NonMonotonicTimeNamesTheLine) {
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.4, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.3, "position_m": [0, 0, 0], "yaw_deg": 0}
)");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ":3: t 0.3 s is not after line 2's 0.4 s (times must increase)");
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
)");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ":2: t 0 s is not after line 1's 0 s (times must increase)");
}

TEST_F(PoseFileConfig, NaNAndMissingKeysNameTheLineAndKey) {
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.1, "position_m": [0, NaN, 0], "yaw_deg": 0}
)");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ":2: invalid JSON (NaN and Infinity are not JSON numbers); expected "
                           "{\"t\": s, \"position_m\": [x, y, z], \"yaw_deg\": d}");
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.1, "position_m": [0, 0, 0], "yaw_deg": null}
)");
  EXPECT_EQ(problem(),
            "arrays[0].pose_file: " + file() + ":2: yaw_deg: expected a number, got null");
  write(R"({"t": 0.0, "position_m": [0, 0, 0]}
)");
  EXPECT_EQ(problem(),
            "arrays[0].pose_file: " + file() + ":1: yaw_deg: required number is missing");
  write(R"({"position_m": [0, 0, 0], "yaw_deg": 0}
)");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() + ":1: t: required number is missing");
  write("[1, 2, 3]\n");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ":1: (top level): expected an object, got a list of 3");
}

TEST_F(PoseFileConfig, GapLargerThanTheBoundIsRefused) {
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.5, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 2.0, "position_m": [0, 0, 0], "yaw_deg": 0}
)");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ":3: t jumps 1.5 s after line 2, more than arrays[0].pose_max_gap_s 1 "
                           "s: the pose in between is unknown");
  // A slower pose source is declared, not guessed.
  EXPECT_EQ(parse(site({{"pose_max_gap_s", 2.0}})).arrays[0].pose.samples().size(), 3U);
}

TEST_F(PoseFileConfig, TurnTooFastForThePoseRateIsRefused) {
  // 170 -> -160 is a 30 deg turn through 180 (fine); -160 -> -100 is 60 deg (too fast).
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 170}
{"t": 0.1, "position_m": [0, 0, 0], "yaw_deg": -160}
{"t": 0.2, "position_m": [0, 0, 0], "yaw_deg": -100}
)");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ":3: yaw turns 60 deg after line 2, more than 45 deg between lines: "
                           "the pose rate is too low for the platform's turn");
}

TEST_F(PoseFileConfig, AbsurdCoordinatesTooFewAndTooLongLines) {
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.1, "position_m": [2e5, 0, 0], "yaw_deg": 0}
)");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ":2: position_m: a coordinate beyond 100 km of the site origin "
                           "(acoustic range is a few km; metres?)");
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
)");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ": 1 pose lines; a pose file needs at least 2 (it is interpolated)");
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.1, "position_m": [0, 0, 0], "yaw_deg": 0, "note": ")" +
        std::string(70000, 'x') + "\"}\n");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() +
                           ":2: line longer than 65536 bytes (a pose line is under 200 bytes)");
  std::filesystem::remove(dir_ / "pose.jsonl");
  EXPECT_EQ(problem(), "arrays[0].pose_file: " + file() + ": cannot open pose file");
}

TEST_F(PoseFileConfig, ASimulatorAboutToWriteThePoseFileOnlyResolvesItsPath) {
  std::vector<std::string> warnings;
  LoadOptions options;
  options.check_recordings = false;
  options.read_pose_files = false;
  const SiteConfig config = parse_site_config(site().dump(), dir_, warnings, options);
  EXPECT_EQ(config.arrays[0].pose_file, dir_ / "pose.jsonl");
  EXPECT_TRUE(config.arrays[0].pose.empty());
  EXPECT_TRUE(config.arrays[0].moving());
}

TEST_F(PoseFileConfig, AttitudeKeysAreBounded) {
  write(R"({"t": 0.0, "position_m": [0, 0, 0], "yaw_deg": 0}
{"t": 0.1, "position_m": [0, 0, 0], "yaw_deg": 0, "pitch_deg": 95}
)");
  EXPECT_EQ(problem(),
            "arrays[0].pose_file: " + file() + ":2: pitch_deg: must be in [-90, 90], got 95");
  json document = site({{"roll_deg", 200.0}});
  document["arrays"][0].erase("pose_file");
  EXPECT_EQ(problem(document), "arrays[0].roll_deg: must be in [-180, 180], got 200");
}

}  // namespace
}  // namespace dronetrack::config::pose_file_test
