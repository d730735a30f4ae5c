// `dronetrack sim` end to end: files written for a bundled scenario; a bad scenario gives one
// line per problem and exit status 1.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <sndfile.h>
#include <sys/wait.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

namespace {

namespace fs = std::filesystem;

struct CommandResult {
  int status = -1;
  std::string out, err;
};

CommandResult run(const std::string& arguments, const fs::path& dir) {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string command =
      std::string(DRONETRACK_BINARY) + " " + arguments + " >" + out.string() + " 2>" + err.string();
  CommandResult result;
  const int raw = std::system(command.c_str());
  result.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  auto slurp = [](const fs::path& path) {
    std::ifstream stream(path);
    std::ostringstream text;
    text << stream.rdbuf();
    return text.str();
  };
  result.out = slurp(out);
  result.err = slurp(err);
  return result;
}

class SimCommand : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sim_cli_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(SimCommand, WritesSiteWavsAndTruthForABundledScenario) {
  const fs::path scenario =
      fs::path(DRONETRACK_SOURCE_DIR) / "config/scenarios/seed002-rectangle.json";
  const CommandResult result = run(
      "sim " + scenario.string() + " --out " + (dir_ / "scene").string() + " --duration-s 1", dir_);
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_NE(result.out.find("wrote " + (dir_ / "scene" / "A1.wav").string()), std::string::npos)
      << result.out;
  for (const char* id : {"A1", "A2"}) {
    SF_INFO info{};
    SNDFILE* file = sf_open((dir_ / "scene" / (std::string(id) + ".wav")).c_str(), SFM_READ, &info);
    ASSERT_NE(file, nullptr) << id;
    sf_close(file);
    EXPECT_EQ(info.frames, 48000);
    EXPECT_EQ(info.channels, 4);
  }
  std::ifstream site_stream(dir_ / "scene" / "site.json");
  const auto site = nlohmann::json::parse(site_stream);
  EXPECT_EQ(site["arrays"][1]["recording"], "A2.wav");
  EXPECT_EQ(site["doa"]["frame_s"], 0.17);
  std::ifstream truth_stream(dir_ / "scene" / "truth.json");
  const auto truth = nlohmann::json::parse(truth_stream);
  EXPECT_EQ(truth["sources"][0]["t"].size(), 101u);
}

TEST_F(SimCommand, MovingArrayGetsItsPoseFileBesideItsRecording) {
  const fs::path scenario =
      fs::path(DRONETRACK_SOURCE_DIR) / "config/scenarios/seed004-multipeak.json";
  const CommandResult result = run(
      "sim " + scenario.string() + " --out " + (dir_ / "scene").string() + " --duration-s 1", dir_);
  ASSERT_EQ(result.status, 0) << result.err;
  const fs::path pose = dir_ / "scene" / "H1.pose.jsonl";
  EXPECT_NE(result.out.find("wrote " + pose.string()), std::string::npos) << result.out;
  std::ifstream pose_stream(pose);
  std::string line, last;
  int lines = 0;
  while (std::getline(pose_stream, line)) ++lines, last = line;
  EXPECT_EQ(lines, 21);  // 20 Hz over the shortened 1 s, both ends
  EXPECT_EQ(nlohmann::json::parse(last)["t"], 1.0);
  std::ifstream site_stream(dir_ / "scene" / "site.json");
  const auto site = nlohmann::json::parse(site_stream);
  EXPECT_EQ(site["arrays"][0]["pose_file"], "H1.pose.jsonl");
  EXPECT_EQ(site["speed_of_sound_mps"], 1500.0);
  SF_INFO info{};
  SNDFILE* file = sf_open((dir_ / "scene" / "H1.wav").c_str(), SFM_READ, &info);
  ASSERT_NE(file, nullptr);
  sf_close(file);
  EXPECT_EQ(info.samplerate, 100000);
  EXPECT_EQ(info.channels, 2);
}

TEST_F(SimCommand, BadScenarioIsOneLinePerProblemAndExitOne) {
  const fs::path scenario = dir_ / "bad.json";
  std::ofstream(scenario) << R"({"site": {"arrays": []}, "sources": [{"id": "D1"}]})";
  const CommandResult result =
      run("sim " + scenario.string() + " --out " + (dir_ / "scene").string(), dir_);
  EXPECT_EQ(result.status, 1);
  const std::string prefix = "dronetrack sim: error: " + scenario.string() + ": ";
  EXPECT_EQ(result.err, prefix + "duration_s: required number is missing\n" + prefix +
                            "site.arrays: at least one array is required\n" + prefix +
                            "sources[0].trajectory: required trajectory is missing\n");
  EXPECT_FALSE(fs::exists(dir_ / "scene"));
}

// Issue 17: alpha-stable bursts in the audio (noise.impulsive) on seed 002's rectangle, 20 s: the
// nodes and the fusion run through them (no crash), the arrays keep reporting DOAs, and the drone
// keeps one track.
TEST_F(SimCommand, NodeAndFusionRunThroughImpulsiveBursts) {
  std::ifstream in(fs::path(DRONETRACK_SOURCE_DIR) / "config/scenarios/seed002-rectangle.json");
  nlohmann::json scenario = nlohmann::json::parse(in);
  scenario["noise"]["impulsive"] = {
      {"snr_db", 0}, {"share", 0.1}, {"burst_s", 0.02}, {"alpha", 1.5}};
  const fs::path scene = dir_ / "scene";
  std::ofstream(dir_ / "bursts.json") << scenario.dump();
  CommandResult result = run(
      "sim " + (dir_ / "bursts.json").string() + " --out " + scene.string() + " --duration-s 20",
      dir_);
  ASSERT_EQ(result.status, 0) << result.err;
  result =
      run("--log-level warn replay " + (scene / "site.json").string() + " --doa-out " +
              (scene / "doa.jsonl").string() + " --tracks-out " + (scene / "tracks.jsonl").string(),
          dir_);
  ASSERT_EQ(result.status, 0) << result.err;
  std::ifstream doas(scene / "doa.jsonl");
  std::size_t doa_lines = 0;
  for (std::string line; std::getline(doas, line);) doa_lines += !line.empty();
  // Two arrays, a frame every 50 ms: 800 frames. A frame (0.17 s, 8.5 slots) holds a burst with
  // probability 1 - 0.9^8.5 = 0.59, and most such frames give no DOA: measured 456.
  std::printf("    %zu DOA lines in 20 s\n", doa_lines);
  EXPECT_GT(doa_lines, 350u);
  EXPECT_LT(doa_lines, 800u);
  result = run("eval --truth " + (scene / "truth.json").string() + " --tracks " +
                   (scene / "tracks.jsonl").string() + " --json " + (dir_ / "eval.json").string(),
               dir_);
  ASSERT_EQ(result.status, 0) << result.err;
  std::ifstream report_file(dir_ / "eval.json");
  const nlohmann::json report = nlohmann::json::parse(report_file);
  std::printf("    RMSE %.3f m, coverage %.1f %%, %d track(s)\n",
              report["position"]["rmse_3d_m"].get<double>(), 100 * report["coverage"].get<double>(),
              report["tracks_seen"].get<int>());
  EXPECT_GE(report["coverage"].get<double>(), 0.85);  // measured 91.0 %
  EXPECT_EQ(report["tracks_seen"].get<int>(), 1);
  EXPECT_EQ(report["id_switches"].get<int>(), 0);
  EXPECT_LT(report["position"]["rmse_3d_m"].get<double>(), 1.0);
}

}  // namespace
