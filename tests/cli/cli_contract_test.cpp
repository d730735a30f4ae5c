// The command line's contract (docs/contract.md, issue 20), case by case against the real
// binary: a failing run keeps earlier results, an output never destroys an input, write errors
// fail the run, an interrupted run leaves TARGET.partial and exits 128 + signal, no input makes
// it hang or balloon, and every error is one line naming the file and key.
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <sndfile.h>
#include <nlohmann/json.hpp>

#include "cli_run.hpp"

namespace {

using namespace dronetrack::cli_test;
namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

// ASan's shadow memory and its quarantine of freed blocks inflate RSS: the bounds are release
// figures. GCC says so with __SANITIZE_ADDRESS__, clang only through __has_feature.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif
constexpr long kMaxRss_kB = 200 * 1024;

void expect_small_rss(const Outcome& outcome) {
  std::printf("    peak RSS of the refused run: %.1f MB\n", outcome.max_rss_kB / 1024.0);
  if (!kSanitized) {
    EXPECT_LT(outcome.max_rss_kB, kMaxRss_kB) << "peak RSS of the refused run";
  }
}

std::size_t count_lines(const std::string& text) {
  return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
}

// Every line of a JSON-lines file parses: nothing was cut mid-line.
void expect_whole_lines(const fs::path& file) {
  const std::string text = read_text(file);
  ASSERT_FALSE(text.empty()) << file;
  EXPECT_EQ(text.back(), '\n') << file << " ends mid-line";
  std::istringstream lines(text);
  std::string line;
  int number = 0;
  while (std::getline(lines, line)) {
    ++number;
    EXPECT_TRUE(json::accept(line)) << file << ":" << number;
  }
}

// No hidden temporary left beside the outputs.
void expect_no_temporaries(const fs::path& dir) {
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    EXPECT_EQ(name.find(".tmp-"), std::string::npos) << "left behind: " << entry.path();
  }
}

class CliContract : public ::testing::Test {
 protected:
  // One short rendered scene shared by every case (rendering is the slow part).
  static void SetUpTestSuite() {
    scene_ = fs::temp_directory_path() / ("dronetrack_cli_contract_" + std::to_string(getpid()));
    fs::remove_all(scene_);
    fs::create_directories(scene_);
    const Outcome rendered = run(
        {"sim", std::string(DRONETRACK_SOURCE_DIR) + "/config/scenarios/perimeter-two-drones.json",
         "--out", (scene_ / "scene").string(), "--duration-s", "3"},
        scene_);
    ASSERT_EQ(rendered.exit_code, 0) << rendered.err;
    // DOAs of the scene, for the fusion-only cases.
    const Outcome replayed =
        run({"replay", (scene_ / "scene/site.json").string(), "--doa-out",
             (scene_ / "doa.jsonl").string(), "--tracks-out", (scene_ / "tracks.jsonl").string()},
            scene_);
    ASSERT_EQ(replayed.exit_code, 0) << replayed.err;
    const Outcome fused =
        run({"replay", (scene_ / "scene/site.json").string(), "--doa-in",
             (scene_ / "doa.jsonl").string(), "--tracks-out", (scene_ / "fused.jsonl").string()},
            scene_);
    ASSERT_EQ(fused.exit_code, 0) << fused.err;
  }
  static void TearDownTestSuite() { fs::remove_all(scene_); }

  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = scene_ / info->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }

  fs::path site() const { return scene_ / "scene/site.json"; }
  // The recording of the scene's array `index`.
  static fs::path recording(int index) {
    return scene_ / "scene" / site_json()["arrays"][index]["recording"].get<std::string>();
  }
  static json site_json() { return json::parse(read_text(scene_ / "scene/site.json")); }
  // A copy of the scene's site in this case's folder, recordings by absolute path, changed by
  // `edit`.
  fs::path site_variant(const std::function<void(json&)>& edit) const {
    json document = site_json();
    for (auto& array : document["arrays"])
      array["recording"] = (scene_ / "scene" / array["recording"].get<std::string>()).string();
    edit(document);
    const fs::path file = dir_ / "site.json";
    write_text(file, document.dump(1));
    return file;
  }
  // Earlier results that a failing run must leave as they are.
  void write_earlier_results() const {
    write_text(dir_ / "t.jsonl", "earlier tracks\n");
    write_text(dir_ / "d.jsonl", "earlier doas\n");
  }
  void expect_earlier_results_kept() const {
    EXPECT_EQ(read_text(dir_ / "t.jsonl"), "earlier tracks\n");
    EXPECT_EQ(read_text(dir_ / "d.jsonl"), "earlier doas\n");
    expect_no_temporaries(dir_);
  }
  std::vector<std::string> replay_args(const fs::path& site_file) const {
    return {"replay",    site_file.string(),         "--tracks-out", (dir_ / "t.jsonl").string(),
            "--doa-out", (dir_ / "d.jsonl").string()};
  }
  // A DOA file as long as `copies` back-to-back copies of the scene's DOAs.
  fs::path long_doa_file(int copies) const {
    const std::string once = read_text(scene_ / "doa.jsonl");
    std::ofstream out(dir_ / "long.jsonl");
    for (int copy = 0; copy < copies; ++copy) {
      std::istringstream lines(once);
      std::string line;
      while (std::getline(lines, line)) {
        json doa = json::parse(line);
        doa["t"] = doa["t"].get<double>() + 3.0 * copy;
        out << doa.dump() << '\n';
      }
    }
    return dir_ / "long.jsonl";
  }

  static inline fs::path scene_;
  fs::path dir_;
};

// One error line on stderr (the log may add info lines before it; none after).
std::string last_line(const std::string& text) {
  std::string trimmed = text;
  while (!trimmed.empty() && trimmed.back() == '\n') trimmed.pop_back();
  const auto newline = trimmed.rfind('\n');
  return newline == std::string::npos ? trimmed : trimmed.substr(newline + 1);
}

// --- 1. A failing run keeps earlier good outputs ---------------------------------------------

// The last time a file's JSON lines carry ("t").
double last_time_s(const fs::path& file) {
  std::istringstream lines(read_text(file));
  std::string line;
  double last_s = -1.0;
  while (std::getline(lines, line)) last_s = std::max(last_s, json::parse(line)["t"].get<double>());
  return last_s;
}

// A replay of recordings reports its tracks up to the audio's end (3 s), past the last DOA,
// which a node stamps its output latency (half a frame, the regression's delay) earlier; a DOA
// file knows no audio end, so the fusion alone stops at its last DOA.
TEST_F(CliContract, AudioReplayReportsTracksToTheRecordingsEnd) {
  const double last_doa_s = last_time_s(scene_ / "doa.jsonl");
  EXPECT_LT(last_doa_s, 2.8);
  EXPECT_NEAR(last_time_s(scene_ / "tracks.jsonl"), 3.0, 1e-9);
  EXPECT_LE(last_time_s(scene_ / "fused.jsonl"), last_doa_s);
}

// Told the audio's end, the fusion alone reports its tracks up to it, as the audio replay did.
TEST_F(CliContract, FusionAloneToldTheAudioEndReportsTracksToIt) {
  const Outcome fused = run({"replay", site().string(), "--doa-in", (scene_ / "doa.jsonl").string(),
                             "--tracks-out", (dir_ / "t.jsonl").string(), "--audio-end-s", "3"},
                            dir_);
  ASSERT_EQ(fused.exit_code, 0) << fused.err;
  EXPECT_NEAR(last_time_s(dir_ / "t.jsonl"), 3.0, 1e-9);
  // The same track lines, to the DOA lines' printed precision (4 decimals of a direction).
  std::istringstream fused_lines(read_text(dir_ / "t.jsonl"));
  std::istringstream audio_lines(read_text(scene_ / "tracks.jsonl"));
  std::string fused_line;
  std::string audio_line;
  int lines = 0;
  while (std::getline(audio_lines, audio_line)) {
    ASSERT_TRUE(std::getline(fused_lines, fused_line)) << "fused ends before line " << lines + 1;
    const json fused_track = json::parse(fused_line);
    const json audio_track = json::parse(audio_line);
    EXPECT_EQ(fused_track["t"], audio_track["t"]) << fused_line;
    EXPECT_EQ(fused_track["id"], audio_track["id"]) << fused_line;
    EXPECT_EQ(fused_track["class"], audio_track["class"]) << fused_line;
    for (int axis = 0; axis < 3; ++axis)
      EXPECT_NEAR(fused_track["position_m"][axis].get<double>(),
                  audio_track["position_m"][axis].get<double>(), 0.05)
          << fused_line;
    ++lines;
  }
  EXPECT_FALSE(std::getline(fused_lines, fused_line)) << "fused has more lines: " << fused_line;
  EXPECT_GT(lines, 20);
}

TEST_F(CliContract, AudioEndBeforeTheLastDoaKeepsEarlierOutputs) {
  write_earlier_results();
  const Outcome outcome =
      run({"replay", site().string(), "--doa-in", (scene_ / "doa.jsonl").string(), "--tracks-out",
           (dir_ / "t.jsonl").string(), "--audio-end-s", "1"},
          dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(last_line(outcome.err).find("--audio-end-s 1 is before the last DOA"),
            std::string::npos)
      << outcome.err;
  expect_earlier_results_kept();
}

TEST_F(CliContract, TruncatedRecordingKeepsEarlierOutputs) {
  const fs::path cut = dir_ / "cut.wav";
  fs::copy_file(recording(0), cut);
  fs::resize_file(cut, fs::file_size(cut) / 2);
  write_earlier_results();
  const Outcome outcome = run(
      replay_args(site_variant([&](json& site) { site["arrays"][0]["recording"] = cut.string(); })),
      dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("truncated"), std::string::npos) << outcome.err;
  expect_earlier_results_kept();
}

TEST_F(CliContract, HttpPortInUseKeepsEarlierOutputs) {
  const int holder = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(holder, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  ASSERT_EQ(::listen(holder, 1), 0);
  socklen_t length = sizeof address;
  ::getsockname(holder, reinterpret_cast<sockaddr*>(&address), &length);
  write_earlier_results();
  auto arguments = replay_args(site());
  arguments.insert(
      arguments.end(),
      {"--http", "127.0.0.1:" + std::to_string(ntohs(address.sin_port)), "--exit-when-done"});
  const Outcome outcome = run(arguments, dir_);
  ::close(holder);
  EXPECT_EQ(outcome.exit_code, 1) << outcome.err;
  expect_earlier_results_kept();
}

TEST_F(CliContract, MalformedHttpAddressIsAUsageError) {
  write_earlier_results();
  for (const char* bad : {"nonsense", "127.0.0.1:99999", "127.0.0.1:", ":80"}) {
    auto arguments = replay_args(site());
    arguments.insert(arguments.end(), {"--http", bad});
    const Outcome outcome = run(arguments, dir_);
    EXPECT_EQ(outcome.exit_code, 2) << bad << ": " << outcome.err;
    EXPECT_EQ(count_lines(outcome.err), 1u) << outcome.err;
  }
  expect_earlier_results_kept();
}

TEST_F(CliContract, OneArrayKeepsEarlierOutputsAndNamesFileAndKey) {
  write_earlier_results();
  const fs::path file =
      site_variant([](json& site) { site["arrays"] = json::array({site["arrays"][0]}); });
  const Outcome outcome = run(replay_args(file), dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_EQ(count_lines(outcome.err), 1u) << outcome.err;
  EXPECT_NE(outcome.err.find(file.string() + ": arrays: the fusion needs at least 2 arrays"),
            std::string::npos)
      << outcome.err;
  expect_earlier_results_kept();
}

TEST_F(CliContract, SixtyFiveArraysKeepEarlierOutputs) {
  write_earlier_results();
  const fs::path file = site_variant([](json& site) {
    const json first = site["arrays"][0];
    site["arrays"] = json::array();
    for (int i = 0; i < 65; ++i) {
      json array = first;
      array["id"] = std::string("N").append(std::to_string(i));  // GCC 12 -Wrestrict on "N" + s
      array["position_m"] = {10.0 * i, 0.0, 1.5};
      site["arrays"].push_back(array);
    }
  });
  const Outcome outcome = run(replay_args(file), dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("arrays: at most 64 arrays"), std::string::npos) << outcome.err;
  expect_earlier_results_kept();
}

TEST_F(CliContract, BandWithoutBinKeepsEarlierOutputsAndNamesTheArray) {
  write_earlier_results();
  const fs::path file = site_variant([](json& site) { site["doa"]["bands_hz"] = {{0, 1}}; });
  const Outcome outcome = run(replay_args(file), dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find(file.string() + ": arrays[0]: with "), std::string::npos)
      << outcome.err;
  EXPECT_NE(outcome.err.find("bands_hz: no FFT bin"), std::string::npos) << outcome.err;
  expect_earlier_results_kept();
}

// A WAV whose header claims 2^31-1 Hz: refused before any buffer is sized from it.
fs::path absurd_rate_wav(const fs::path& dir) {
  const fs::path file = dir / "absurd.wav";
  SF_INFO info{};
  info.samplerate = 48000;
  info.channels = 4;
  info.format = SF_FORMAT_WAV | SF_FORMAT_PCM_16;
  SNDFILE* handle = sf_open(file.c_str(), SFM_WRITE, &info);
  std::vector<short> samples(4 * 200000, 100);
  sf_write_short(handle, samples.data(), static_cast<sf_count_t>(samples.size()));
  sf_close(handle);
  std::fstream patch(file, std::ios::in | std::ios::out | std::ios::binary);
  const unsigned char rate[4] = {0xFF, 0xFF, 0xFF, 0x7F};  // fmt chunk at 12: rate at 24
  patch.seekp(24);
  patch.write(reinterpret_cast<const char*>(rate), 4);
  return file;
}

TEST_F(CliContract, AbsurdSampleRateIsRefusedEarlyInLittleMemory) {
  write_earlier_results();
  const fs::path wav = absurd_rate_wav(dir_);
  const Outcome outcome = run(
      replay_args(site_variant([&](json& site) { site["arrays"][2]["recording"] = wav.string(); })),
      dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(
      outcome.err.find("arrays[2].recording: " + wav.string() + ": sample rate 2147483647 Hz"),
      std::string::npos)
      << outcome.err;
  expect_small_rss(outcome);
  expect_earlier_results_kept();
}

TEST_F(CliContract, UnwritableTracksOutKeepsDoaOut) {
  write_earlier_results();
  const Outcome outcome = run({"replay", site().string(), "--doa-out", (dir_ / "d.jsonl").string(),
                               "--tracks-out", (dir_ / "no/such/folder/t.jsonl").string()},
                              dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("does not exist"), std::string::npos) << outcome.err;
  expect_earlier_results_kept();
}

// --- 2. An output that is also an input ------------------------------------------------------

TEST_F(CliContract, OutputOverARecordingIsRefused) {
  const std::string before = read_text(recording(1));
  const Outcome outcome =
      run({"replay", site().string(), "--tracks-out", recording(1).string()}, dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("is an input (arrays[1].recording)"), std::string::npos)
      << outcome.err;
  EXPECT_EQ(read_text(recording(1)), before);
}

TEST_F(CliContract, OutputOverTheSiteConfigIsRefused) {
  const fs::path file = site_variant([](json&) {});
  const std::string before = read_text(file);
  // Through another spelling of the same path.
  const fs::path other_spelling = dir_ / "." / "site.json";
  const Outcome outcome = run({"replay", file.string(), "--doa-out", other_spelling.string(),
                               "--tracks-out", (dir_ / "t.jsonl").string()},
                              dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("is an input (the site config)"), std::string::npos) << outcome.err;
  EXPECT_EQ(read_text(file), before);
}

TEST_F(CliContract, TwoOutputsInOneFileAreRefused) {
  const fs::path same = dir_ / "both.jsonl";
  const Outcome outcome = run(
      {"replay", site().string(), "--doa-out", same.string(), "--tracks-out", same.string()}, dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("two outputs in one file would interleave"), std::string::npos)
      << outcome.err;
  EXPECT_FALSE(fs::exists(same));
}

// --- 3. Write errors -------------------------------------------------------------------------

TEST_F(CliContract, FullDiskFailsTheRun) {
  const Outcome outcome = run({"replay", site().string(), "--doa-in",
                               (scene_ / "doa.jsonl").string(), "--tracks-out", "/dev/full"},
                              dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("/dev/full: write failed"), std::string::npos) << outcome.err;
}

TEST_F(CliContract, UnwritableSystemFileFailsTheRun) {
  const Outcome outcome =
      run({"replay", site().string(), "--doa-in", (scene_ / "doa.jsonl").string(), "--tracks-out",
           (dir_ / "t.jsonl").string(), "--doa-out", "/proc/version"},
          dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("/proc/version"), std::string::npos) << outcome.err;
  EXPECT_FALSE(fs::exists(dir_ / "t.jsonl"));
}

TEST_F(CliContract, ClosedStdoutFailsTheRun) {
  RunOptions options;
  options.close_stdout = true;
  const Outcome outcome =
      run({"replay", site().string(), "--doa-in", (scene_ / "doa.jsonl").string()}, dir_, options);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("stdout: is closed"), std::string::npos) << outcome.err;
}

// --- 4. Interrupted runs ---------------------------------------------------------------------

void expect_interrupted(const Outcome& outcome, int signal, const fs::path& target) {
  EXPECT_FALSE(outcome.timed_out);
  EXPECT_EQ(outcome.exit_code, 128 + signal) << outcome.err;
  const std::string last = last_line(outcome.err);
  EXPECT_NE(last.find("partial results kept in "), std::string::npos) << outcome.err;
  EXPECT_NE(last.find(target.string() + ".partial"), std::string::npos) << outcome.err;
  EXPECT_FALSE(fs::exists(target)) << "an interrupted run must not look complete";
  expect_whole_lines(target.string() + ".partial");
}

TEST_F(CliContract, SigintDuringDoaReplayLeavesWholeLinesMarkedPartial) {
  const fs::path doas = long_doa_file(100);
  for (int signal : {SIGINT, SIGTERM}) {
    RunOptions options;
    options.signal = signal;
    // Once the fusion is writing (stdio has flushed its first buffer to the temporary).
    options.signal_when = [this] {
      for (const auto& entry : fs::directory_iterator(dir_)) {
        if (entry.path().filename().string().rfind(".t.jsonl.tmp-", 0) == 0 &&
            fs::file_size(entry.path()) > 0)
          return true;
      }
      return false;
    };
    const Outcome outcome = run({"replay", site().string(), "--doa-in", doas.string(),
                                 "--tracks-out", (dir_ / "t.jsonl").string()},
                                dir_, options);
    expect_interrupted(outcome, signal, dir_ / "t.jsonl");
    fs::remove(dir_ / "t.jsonl.partial");
  }
}

TEST_F(CliContract, SighupDuringAudioReplayLeavesWholeLinesMarkedPartial) {
  RunOptions options;
  options.signal = SIGHUP;
  options.signal_after = 1500ms;
  auto arguments = replay_args(site());
  arguments.push_back("--realtime");
  const Outcome outcome = run(arguments, dir_, options);
  expect_interrupted(outcome, SIGHUP, dir_ / "t.jsonl");
  expect_whole_lines(dir_ / "d.jsonl.partial");
  expect_no_temporaries(dir_);
}

TEST_F(CliContract, RecordingTruncatedMidRunFailsAndMarksPartial) {
  const fs::path copy = dir_ / "A3.wav";
  fs::copy_file(recording(2), copy);
  const fs::path file =
      site_variant([&](json& site) { site["arrays"][2]["recording"] = copy.string(); });
  RunOptions options;
  options.signal_after = 1200ms;
  options.while_running = [&] { fs::resize_file(copy, fs::file_size(copy) * 2 / 3); };
  auto arguments = replay_args(file);
  arguments.push_back("--realtime");
  const Outcome outcome = run(arguments, dir_, options);
  EXPECT_EQ(outcome.exit_code, 1) << outcome.err;
  EXPECT_NE(outcome.err.find("truncated while being read"), std::string::npos) << outcome.err;
  EXPECT_FALSE(fs::exists(dir_ / "t.jsonl"));
  expect_whole_lines(dir_ / "t.jsonl.partial");
}

TEST_F(CliContract, SigintDuringSimWritesNothing) {
  RunOptions options;
  options.signal = SIGINT;
  // Once sim has made its output directory: its handlers are in place (main installs them
  // first) and the render is under way. A fixed delay raced the process's start under ASan.
  options.signal_when = [this] { return fs::exists(dir_ / "scene"); };
  const Outcome outcome = run(
      {"sim", std::string(DRONETRACK_SOURCE_DIR) + "/config/scenarios/perimeter-two-drones.json",
       "--out", (dir_ / "scene").string()},
      dir_, options);
  EXPECT_EQ(outcome.exit_code, 130) << outcome.err;
  EXPECT_NE(outcome.err.find("sim: interrupted by SIGINT; nothing written"), std::string::npos)
      << outcome.err;
  EXPECT_TRUE(fs::is_empty(dir_ / "scene"));
}

TEST_F(CliContract, CompleteRunReplacesTheTargetAndClearsAnOldPartial) {
  write_text(dir_ / "t.jsonl.partial", "an older interrupted run\n");
  write_earlier_results();
  const Outcome outcome =
      run({"replay", site().string(), "--doa-in", (scene_ / "doa.jsonl").string(), "--tracks-out",
           (dir_ / "t.jsonl").string()},
          dir_);
  EXPECT_EQ(outcome.exit_code, 0) << outcome.err;
  EXPECT_EQ(read_text(dir_ / "t.jsonl"), read_text(scene_ / "fused.jsonl"));
  EXPECT_FALSE(fs::exists(dir_ / "t.jsonl.partial"));
  expect_no_temporaries(dir_);
}

// --- 5. Hangs --------------------------------------------------------------------------------

TEST_F(CliContract, AbsurdDoaTimesAreRefusedQuickly) {
  for (const char* time : {"1e9", "1e12", "1e300"}) {
    std::string lines = read_text(scene_ / "doa.jsonl");
    lines += R"({"t": )" + std::string(time) + R"(, "array": "A1", "direction": [1, 0, 0]})" + "\n";
    write_text(dir_ / "stray.jsonl", lines);
    RunOptions options;
    options.timeout = 20s;
    const Outcome outcome =
        run({"replay", site().string(), "--doa-in", (dir_ / "stray.jsonl").string(), "--tracks-out",
             (dir_ / "t.jsonl").string()},
            dir_, options);
    EXPECT_FALSE(outcome.timed_out) << time;
    EXPECT_EQ(outcome.exit_code, 1) << time << ": " << outcome.err;
    EXPECT_EQ(count_lines(outcome.err), 1u) << outcome.err;
    EXPECT_NE(outcome.err.find("stray.jsonl:" + std::to_string(count_lines(lines)) + ": t"),
              std::string::npos)
        << outcome.err;
  }
}

TEST_F(CliContract, DoasOnAnotherClockStartTheTicksThere) {
  // UNIX time: a span of 3 s, 1.8e9 s from zero. The ticks start at the first DOA.
  std::ofstream out(dir_ / "unix.jsonl");
  std::istringstream lines(read_text(scene_ / "doa.jsonl"));
  std::string line;
  while (std::getline(lines, line)) {
    json doa = json::parse(line);
    doa["t"] = doa["t"].get<double>() + 1.8e9;
    out << doa.dump() << '\n';
  }
  out.close();
  RunOptions options;
  options.timeout = 30s;
  const Outcome outcome =
      run({"replay", site().string(), "--doa-in", (dir_ / "unix.jsonl").string(), "--tracks-out",
           (dir_ / "t.jsonl").string()},
          dir_, options);
  EXPECT_EQ(outcome.exit_code, 0) << outcome.err;
  const auto shifted = static_cast<long>(count_lines(read_text(dir_ / "t.jsonl")));
  const auto original = static_cast<long>(count_lines(read_text(scene_ / "fused.jsonl")));
  EXPECT_GT(original, 20);
  EXPECT_NEAR(shifted, original, 4);
}

TEST_F(CliContract, TinyEvalTickIsRefusedQuickly) {
  RunOptions options;
  options.timeout = 20s;
  const Outcome outcome = run({"eval", "--truth", (scene_ / "scene/truth.json").string(),
                               "--tracks", (scene_ / "tracks.jsonl").string(), "--tick-s", "1e-9"},
                              dir_, options);
  EXPECT_FALSE(outcome.timed_out);
  EXPECT_EQ(outcome.exit_code, 1) << outcome.err;
  EXPECT_NE(outcome.err.find("--tick-s"), std::string::npos) << outcome.err;
}

TEST_F(CliContract, NonFiniteNumbersAreUsageErrors) {
  for (const char* value : {"nan", "inf", "-inf", "1e999"}) {
    const Outcome outcome = run({"replay", site().string(), "--max-duration-s", value}, dir_);
    EXPECT_EQ(outcome.exit_code, 2) << value << ": " << outcome.err;
    EXPECT_EQ(count_lines(outcome.err), 1u) << outcome.err;
  }
  const Outcome eval = run({"eval", "--truth", (scene_ / "scene/truth.json").string(), "--tracks",
                            (scene_ / "tracks.jsonl").string(), "--gate-m", "nan"},
                           dir_);
  EXPECT_EQ(eval.exit_code, 2) << eval.err;
}

// --- 6. Memory before validation -------------------------------------------------------------

TEST_F(CliContract, TenThousandArraysAreRefusedInLittleMemory) {
  const fs::path file = site_variant([](json& site) {
    const json first = site["arrays"][0];
    site["arrays"] = json::array();
    for (int i = 0; i < 10000; ++i) {
      json array = first;
      array["id"] = std::string("N").append(std::to_string(i));  // GCC 12 -Wrestrict on "N" + s
      site["arrays"].push_back(array);
    }
  });
  const Outcome outcome = run(replay_args(file), dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("arrays: at most 64 arrays"), std::string::npos) << outcome.err;
  expect_small_rss(outcome);
}

TEST_F(CliContract, HugeDoaLineIsRefusedInLittleMemory) {
  {
    std::ofstream out(dir_ / "huge.jsonl");
    out << R"({"t": 0.1, "array": "A1", "direction": [1, 0, 0], "pad": [)";
    for (int i = 0; i < 10'000'000; ++i) out << "0,";
    out << "0]}\n";
  }
  ASSERT_GT(fs::file_size(dir_ / "huge.jsonl"), 20'000'000u);
  const Outcome outcome =
      run({"replay", site().string(), "--doa-in", (dir_ / "huge.jsonl").string(), "--tracks-out",
           (dir_ / "t.jsonl").string()},
          dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("huge.jsonl:1: line longer than"), std::string::npos) << outcome.err;
  expect_small_rss(outcome);
}

TEST_F(CliContract, HugeConfigIsRefusedInLittleMemory) {
  {
    std::ofstream out(dir_ / "site.json");
    std::string text = read_text(site());
    while (!text.empty() && text.back() != '}') text.pop_back();  // trailing whitespace
    text.pop_back();                                              // the closing brace
    out << text;
    for (int i = 0; i < 4'000'000; ++i) out << ",\"unknown" << i << "\":0";
    out << "}\n";
  }
  const Outcome outcome = run(replay_args(dir_ / "site.json"), dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_NE(outcome.err.find("a site config may be at most 4 MiB"), std::string::npos)
      << outcome.err;
  expect_small_rss(outcome);
}

TEST_F(CliContract, ManyUnknownKeysPrintAFewWarnings) {
  const fs::path file = site_variant([](json& site) {
    for (int i = 0; i < 100'000; ++i) site["unknown" + std::to_string(i)] = 0;
  });
  const Outcome outcome = run({"replay", file.string(), "--doa-in", (scene_ / "doa.jsonl").string(),
                               "--tracks-out", (dir_ / "t.jsonl").string()},
                              dir_);
  EXPECT_EQ(outcome.exit_code, 0) << outcome.err.substr(0, 2000);
  EXPECT_LT(outcome.err.size(), 10'000u);
  EXPECT_NE(outcome.err.find("more warnings"), std::string::npos);
}

// --- 9. Errors name the file and key; bounds on the site -------------------------------------

TEST_F(CliContract, OverflowingNumberInADoaLineNamesFileAndLine) {
  write_text(dir_ / "overflow.jsonl", R"({"t": 1e999, "array": "A1", "direction": [1, 0, 0]})"
                                      "\n");
  const Outcome outcome =
      run({"replay", site().string(), "--doa-in", (dir_ / "overflow.jsonl").string(),
           "--tracks-out", (dir_ / "t.jsonl").string()},
          dir_);
  EXPECT_EQ(outcome.exit_code, 1);
  EXPECT_EQ(count_lines(outcome.err), 1u) << outcome.err;
  EXPECT_NE(outcome.err.find("overflow.jsonl:1: invalid JSON: number overflow"), std::string::npos)
      << outcome.err;
}

struct SiteCase {
  const char* name;
  std::function<void(json&)> edit;
  const char* expected;  // in the error line, after "SITE: "
};

TEST_F(CliContract, SiteBoundsNameTheKey) {
  const SiteCase cases[] = {
      {"band of 1e300 Hz",
       [](json& s) {
         s["doa"]["bands_hz"] = {{300, 1e300}};
       },
       "doa.bands_hz[0]: high_hz above 500 kHz"},
      {"array at 1e308 m",
       [](json& s) {
         s["arrays"][1]["position_m"] = {1e308, 0, 1.5};
       },
       "arrays[1].position_m: a coordinate beyond 100 km"},
      {"mic 1e6 m away",
       [](json& s) {
         s["arrays"][0]["mics_m"][3] = {1e6, 0, 0};
       },
       "arrays[0].mics_m[3]: mic 1e+06 m from its array's centre"},
      {"mics 50 m apart",
       [](json& s) {
         s["arrays"][0]["mics_m"][3] = {50, 0, 0};
       },
       "exceeds half a frame"},
      {"zone of no area",
       [](json& s) {
         s["zones"] = {{{"name", "line"}, {"polygon_m", {{0, 0}, {10, 0}, {20, 0}}}}};
       },
       "zones[0].polygon_m: encloses 0 m^2"},
  };
  for (const SiteCase& site_case : cases) {
    const fs::path file = site_variant(site_case.edit);
    const Outcome outcome = run(replay_args(file), dir_);
    EXPECT_EQ(outcome.exit_code, 1) << site_case.name;
    EXPECT_NE(outcome.err.find(file.string() + ": "), std::string::npos) << outcome.err;
    EXPECT_NE(outcome.err.find(site_case.expected), std::string::npos)
        << site_case.name << ": " << outcome.err;
    EXPECT_EQ(outcome.err.find("-2147483648"), std::string::npos) << outcome.err;
  }
}

}  // namespace
