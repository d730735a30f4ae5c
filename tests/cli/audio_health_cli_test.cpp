// Bad audio must not pass in silence (issue 20): the real `dronetrack replay` on a tiny site
// whose second array's recording is broken (a channel all NaN; everything scaled by 1e30) runs
// to the end (exit 0) and says so on stderr, once per channel and problem, naming the array and
// the channel, plus one summary line per array at the end. The healthy array says nothing.
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sndfile.h>

namespace {

namespace fs = std::filesystem;

constexpr int kRate = 16000;
constexpr int kChannels = 4;
constexpr double kSeconds = 3.0;

struct CommandResult {
  int status = -1;
  std::string err;
};

CommandResult run(const std::string& arguments, const fs::path& dir) {
  const fs::path err = dir / "stderr.txt";
  const std::string command = std::string(DRONETRACK_BINARY) + " " + arguments + " >" +
                              (dir / "stdout.txt").string() + " 2>" + err.string();
  CommandResult result;
  const int raw = std::system(command.c_str());
  result.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  std::ifstream stream(err);
  std::ostringstream text;
  text << stream.rdbuf();
  result.err = text.str();
  return result;
}

// Independent noise per channel, RMS ~0.05: a healthy, quiet recording.
std::vector<float> noise() {
  const auto frames = static_cast<std::size_t>(kSeconds * kRate);
  std::vector<float> samples(frames * kChannels);
  unsigned state = 12345;
  for (float& sample : samples) {
    state = state * 1664525U + 1013904223U;
    sample = 0.1F * (static_cast<float>(state >> 8) / static_cast<float>(1U << 24) - 0.5F) * 1.7F;
  }
  return samples;
}

void write_wav(const fs::path& file, const std::vector<float>& samples) {
  SF_INFO info{};
  info.samplerate = kRate;
  info.channels = kChannels;
  info.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
  SNDFILE* handle = sf_open(file.c_str(), SFM_WRITE, &info);
  ASSERT_NE(handle, nullptr) << sf_strerror(nullptr);
  // Float WAVs keep NaN and values beyond full scale as written.
  const auto frames = static_cast<sf_count_t>(samples.size() / kChannels);
  ASSERT_EQ(sf_writef_float(handle, samples.data(), frames), frames);
  sf_close(handle);
}

int lines_containing(const std::string& text, const std::string& what) {
  int count = 0;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) count += line.find(what) != std::string::npos;
  return count;
}

class AudioHealthCli : public testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("audio_health_cli_" + std::to_string(::getpid()) + "_" +
                                     testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "site.json") << R"({"arrays": [
      {"id": "A1", "position_m": [0, 0, 1.5], "recording": "A1.wav",
       "mics_m": [[0,0,0.5], [0.471,0,-0.167], [-0.236,0.408,-0.167], [-0.236,-0.408,-0.167]]},
      {"id": "A2", "position_m": [20, 0, 1.5], "recording": "A2.wav",
       "mics_m": [[0,0,0.5], [0.471,0,-0.167], [-0.236,0.408,-0.167], [-0.236,-0.408,-0.167]]}]})";
    write_wav(dir_ / "A1.wav", noise());
  }
  void TearDown() override { fs::remove_all(dir_); }

  CommandResult replay() {
    return run("--log-level warn replay " + (dir_ / "site.json").string() + " --tracks-out " +
                   (dir_ / "tracks.jsonl").string(),
               dir_);
  }

  fs::path dir_;
};

TEST_F(AudioHealthCli, AnAllNaNChannelIsWarnedOnceAndTheRunCompletes) {
  std::vector<float> broken = noise();
  for (std::size_t n = 2; n < broken.size(); n += kChannels)
    broken[n] = std::numeric_limits<float>::quiet_NaN();
  write_wav(dir_ / "A2.wav", broken);

  const CommandResult result = replay();
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(
      lines_containing(result.err, "A2 channel 2: all samples non-finite (NaN/inf) since 0.00 s"),
      1)
      << result.err;
  EXPECT_EQ(lines_containing(result.err,
                             "replay: audio problems: A2 channel 2: non-finite 48000 "
                             "samples (100 %)"),
            1)
      << result.err;
  EXPECT_EQ(lines_containing(result.err, "A1"), 0) << result.err;
  EXPECT_TRUE(fs::exists(dir_ / "tracks.jsonl"));
}

TEST_F(AudioHealthCli, ARecordingScaledBy1e30IsWarnedPerChannelAndTheRunCompletes) {
  std::vector<float> scaled = noise();
  for (float& sample : scaled) sample *= 1e30F;
  write_wav(dir_ / "A2.wav", scaled);

  const CommandResult result = replay();
  ASSERT_EQ(result.status, 0) << result.err;
  for (int channel = 0; channel < kChannels; ++channel) {
    EXPECT_EQ(lines_containing(result.err,
                               "A2 channel " + std::to_string(channel) + ": absurd level (peak "),
              1)
        << result.err;
  }
  EXPECT_EQ(lines_containing(result.err, "replay: audio problems: A2 channel 0: absurd level"), 1)
      << result.err;
  EXPECT_EQ(lines_containing(result.err, "A1"), 0) << result.err;
}

}  // namespace
