// Fault cases of the distributed mode (issue 18, docs/deployment.md "Faults"), with the real
// binary on loopback, each test in its own DDS domain, on the 14 s perimeter pass of
// perimeter-short.json (three arrays, one drone crossing from t 0 to 12.5 s), looped:
// - a node restarted with its clock 8 s ahead, then 5 s behind, then right again: the site's
//   clock is not dragged (no track time runs ahead of the wall clock), the two good arrays keep
//   the track, the jumped node's samples are refused and counted (ahead of the site clock / too
//   late) and contribute nothing, and once its clock is right it contributes again;
// - audio dropouts: a recording with 2 s of digital silence on every channel: the node counts
//   one dropout in NodeStatus, publishes no DOA from inside the gap, and resumes after it;
// - the fusion SIGKILLed while the nodes run and started again: a new confirmed track within a
//   bounded time, and no track id the first instance published is published by the second.
#include <gtest/gtest.h>
#include <sndfile.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"
#include "tests/dds/dds_test_support.hpp"
#include "tests/dds/process_support.hpp"

namespace {

using namespace dronetrack::dds::testing;
namespace dds = dronetrack::dds;

constexpr int kClockJumpDomain = 141;
constexpr int kDropoutDomain = 142;
constexpr int kFusionRestartDomain = 143;
constexpr std::uint64_t kN3 = 1u << 2;  // array index 2 in contributing_arrays

struct TrackSample {
  dds_instance_handle_t writer = 0;
  int id = 0;
  double time_s = 0.0;
  int status = 0;  // 0 tentative, 1 confirmed, 2 coasting
  std::uint64_t arrays = 0;
  double received_unix_s = 0.0;
};

// A Track subscriber, as an operator's client would be.
class TrackListener {
 public:
  explicit TrackListener(const dds::Participant& participant)
      : topic_(participant), reader_(participant, topic_, qos()) {}

  // Takes samples until `done` says so or the wall clock passes `until_unix_s`.
  template <class Done>
  void collect(double until_unix_s, Done done) {
    while (unix_now_s() < until_unix_s && !done()) {
      reader_.wait(50ms);
      for (;;) {
        dds::Samples<dronetrack_Track> samples = reader_.take();
        if (samples.empty()) break;
        for (std::size_t i = 0; i < samples.size(); ++i) {
          if (!samples.info(i).valid_data) continue;  // disposed: the track ended
          const dronetrack_Track& track = samples.data(i);
          received.push_back({samples.info(i).publication_handle, track.id,
                              dds::ns_to_seconds(track.time_ns), track.status,
                              track.contributing_arrays, unix_now_s()});
        }
      }
    }
  }
  void collect_until(double until_unix_s) {
    collect(until_unix_s, [] { return false; });
  }

  std::vector<TrackSample> received;

 private:
  static dds::Qos qos() {
    dds::Qos qos;
    dds::track_reader_qos(qos);
    return qos;
  }
  dds::Topic<dronetrack_Track> topic_;
  dds::Reader<dronetrack_Track> reader_;
};

// The number in the fusion's closing summary before `label` (e.g. "too late "), or -1.
long summary_count(const std::string& log, const std::string& label) {
  const auto summary = log.find("DOAs received");
  if (summary == std::string::npos) return -1;
  const auto at = log.find(label, summary);
  if (at == std::string::npos) return -1;
  return std::strtol(log.c_str() + at + label.size(), nullptr, 10);
}

class DdsFaults : public ::testing::Test {
 protected:
  void SetUp() override {
    use_loopback();
    dir_ = fs::temp_directory_path() /
           (std::string("dronetrack-faults-") +
            ::testing::UnitTest::GetInstance()->current_test_info()->name() + "-" +
            std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    site_ = (dir_ / "scene" / "site.json").string();
    Process sim(
        {binary_, "sim", std::string(DRONETRACK_SOURCE_DIR) + "/tests/dds/perimeter-short.json",
         "--out", (dir_ / "scene").string()},
        dir_ / "sim.out", dir_ / "sim.err");
    ASSERT_EQ(sim.wait_exit(120s), 0) << read_text(dir_ / "sim.err");
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // A node replaying its array's recording in real time, looped, recording time 0 due at
  // `epoch_unix_s` (its clock: a node given another epoch stamps its DOAs that much off).
  std::unique_ptr<Process> node(const std::string& id, double epoch_unix_s, int domain,
                                const std::string& name) {
    char epoch[32];
    std::snprintf(epoch, sizeof epoch, "%.3f", epoch_unix_s);
    return std::make_unique<Process>(
        std::vector<std::string>{binary_, "node", site_, "--array", id, "--realtime", "--loop",
                                 "--epoch", epoch, "--domain", std::to_string(domain)},
        dir_ / (name + ".out"), dir_ / (name + ".err"));
  }
  std::unique_ptr<Process> fusion(int domain, const std::string& name,
                                  std::vector<std::string> extra = {}) {
    std::vector<std::string> arguments{binary_,
                                       "fusion",
                                       site_,
                                       "--domain",
                                       std::to_string(domain),
                                       "--tracks-out",
                                       (dir_ / "tracks.jsonl").string()};
    arguments.insert(arguments.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(arguments, dir_ / (name + ".out"), dir_ / (name + ".err"));
  }
  // SIGTERM, and the clean exit a signal gives (128 + SIGTERM).
  static void stop(Process& process, const fs::path& log) {
    process.signal(SIGTERM);
    EXPECT_EQ(process.wait_exit(10s), (128 + SIGTERM) << 8) << read_text(log);
  }

  const std::string binary_ = DRONETRACK_BINARY;
  fs::path dir_;
  std::string site_;
};

TEST_F(DdsFaults, NodeClockJumpsAreRefusedCountedAndRecovered) {
  dds::Participant participant(kClockJumpDomain);
  TrackListener tracks(participant);
  auto fusion_process = fusion(kClockJumpDomain, "fusion");
  const double epoch = std::floor(unix_now_s()) + 3.0;  // discovery is done by then
  auto n1 = node("N1", epoch, kClockJumpDomain, "N1");
  auto n2 = node("N2", epoch, kClockJumpDomain, "N2");
  auto n3 = node("N3", epoch, kClockJumpDomain, "N3");

  // Phases in recording (= site) time: all well until 4 s; N3 restarted 8 s ahead until 6.5 s;
  // restarted 5 s behind until 9 s; then restarted right.
  constexpr double kAheadFrom_s = 4.0, kBehindFrom_s = 6.5, kRightFrom_s = 9.0;
  auto restart_n3 = [&](double at_s, double clock_offset_s, const std::string& name) {
    tracks.collect_until(epoch + at_s);
    stop(*n3, dir_ / "N3.err");
    n3 = node("N3", epoch - clock_offset_s, kClockJumpDomain, name);
  };
  restart_n3(kAheadFrom_s, 8.0, "N3-ahead");
  restart_n3(kBehindFrom_s, -5.0, "N3-behind");
  restart_n3(kRightFrom_s, 0.0, "N3-right");
  // Recovery: N3 contributes to a track again, within a bounded time.
  bool recovered = false;
  tracks.collect(epoch + 20.0, [&] {
    recovered = std::any_of(tracks.received.begin(), tracks.received.end(),
                            [&](auto& s) { return s.time_s > kRightFrom_s && (s.arrays & kN3); });
    return recovered;
  });
  for (auto* process : {n1.get(), n2.get(), n3.get()}) stop(*process, dir_ / "N1.err");
  stop(*fusion_process, dir_ / "fusion.err");
  const std::string log = read_text(dir_ / "fusion.err");

  ASSERT_FALSE(tracks.received.empty()) << log;
  double worst_lead_s = -1e9;
  int good_ticks_while_jumped = 0;
  std::set<long> ticks_while_jumped;
  for (const TrackSample& sample : tracks.received) {
    // The site's clock follows the good nodes: no track is stamped ahead of the wall clock by
    // more than the output tick and DDS delivery (an 8 s jump would show as 8 s).
    worst_lead_s = std::max(worst_lead_s, sample.time_s - (sample.received_unix_s - epoch));
    // While N3's clock is off (after its last good DOAs have aged out of the 1 s memory, and
    // before the restarted node's first DOAs, which may reach ticks up to 1 s older), it
    // contributes nothing; N1 and N2 keep the track confirmed.
    if (sample.time_s > kAheadFrom_s + 1.5 && sample.time_s < kRightFrom_s - 1.0) {
      EXPECT_FALSE(sample.arrays & kN3) << "t " << sample.time_s;
      if (sample.status == 1 && (sample.arrays & 0b11) == 0b11) {
        ++good_ticks_while_jumped;
        ticks_while_jumped.insert(std::lround(sample.time_s * 10.0));
      }
    }
  }
  std::printf(
      "track time lead over the wall clock at most %.2f s; %zu ticks of %d confirmed by "
      "N1+N2 while N3's clock was off\n",
      worst_lead_s, ticks_while_jumped.size(), good_ticks_while_jumped);
  EXPECT_LT(worst_lead_s, 1.5);
  // 2.5 s of 10 Hz ticks (5.5 .. 8 s): most of them carry the confirmed track.
  EXPECT_GE(ticks_while_jumped.size(), 18U) << log;
  EXPECT_TRUE(recovered) << log;
  const long ahead = summary_count(log, "ahead of the site clock ");
  const long too_late = summary_count(log, "too late ");
  std::printf("fusion: %ld samples ahead of the site clock, %ld DOAs too late\n", ahead, too_late);
  EXPECT_GT(ahead, 10) << log;     // N3's DOAs and statuses while 8 s ahead
  EXPECT_GT(too_late, 10) << log;  // N3's DOAs while 5 s behind
}

TEST_F(DdsFaults, AudioDropoutIsCountedAndYieldsNoDoas) {
  // N1's recording with 4.0 .. 6.0 s zeroed on every channel: what a capture gap delivers.
  constexpr double kGapFrom_s = 4.0, kGapTo_s = 6.0;
  const fs::path gapped = dir_ / "N1-gap.wav";
  {
    SF_INFO info{};
    SNDFILE* in = sf_open((dir_ / "scene" / "N1.wav").c_str(), SFM_READ, &info);
    ASSERT_NE(in, nullptr) << sf_strerror(nullptr);
    std::vector<float> samples(static_cast<std::size_t>(info.frames * info.channels));
    ASSERT_EQ(sf_readf_float(in, samples.data(), info.frames), info.frames);
    sf_close(in);
    const auto from = static_cast<std::size_t>(kGapFrom_s * info.samplerate) * info.channels;
    const auto to = static_cast<std::size_t>(kGapTo_s * info.samplerate) * info.channels;
    std::fill(samples.begin() + static_cast<std::ptrdiff_t>(from),
              samples.begin() + static_cast<std::ptrdiff_t>(to), 0.0F);
    SF_INFO format{};
    format.samplerate = info.samplerate;
    format.channels = info.channels;
    format.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
    SNDFILE* out = sf_open(gapped.c_str(), SFM_WRITE, &format);
    ASSERT_NE(out, nullptr) << sf_strerror(nullptr);
    ASSERT_EQ(sf_writef_float(out, samples.data(), info.frames), info.frames) << sf_strerror(out);
    sf_close(out);
  }
  dds::Participant participant(kDropoutDomain);
  dds::Topic<dronetrack_Doa> doa_topic(participant);
  dds::Topic<dronetrack_NodeStatus> status_topic(participant);
  dds::Qos doa_qos, status_qos;
  dds::doa_reader_qos(doa_qos);
  dds::status_reader_qos(status_qos);
  dds::Reader<dronetrack_Doa> doas(participant, doa_topic, doa_qos);
  dds::Reader<dronetrack_NodeStatus> statuses(participant, status_topic, status_qos);
  // As fast as it can (no --realtime): the 14 s take a second or two.
  Process node({binary_, "node", site_, "--array", "N1", "--recording", gapped.string(), "--domain",
                std::to_string(kDropoutDomain)},
               dir_ / "node.out", dir_ / "node.err");
  std::vector<double> doa_times;
  std::vector<std::pair<double, std::int64_t>> dropouts;  // (status time, dropouts)
  auto take = [&] {
    for (bool more = true; more;) {
      dds::Samples<dronetrack_Doa> s = doas.take();
      more = !s.empty();
      for (std::size_t i = 0; i < s.size(); ++i) {
        if (s.info(i).valid_data) doa_times.push_back(dds::ns_to_seconds(s.data(i).time_ns));
      }
    }
    for (bool more = true; more;) {
      dds::Samples<dronetrack_NodeStatus> s = statuses.take();
      more = !s.empty();
      for (std::size_t i = 0; i < s.size(); ++i) {
        if (s.info(i).valid_data) {
          dropouts.emplace_back(dds::ns_to_seconds(s.data(i).time_ns), s.data(i).dropouts);
        }
      }
    }
  };
  const auto deadline = Clock::now() + 60s;
  while (!node.wait_exit(0s) && Clock::now() < deadline) {
    doas.wait(50ms);
    take();
  }
  ASSERT_EQ(node.wait_exit(10s), 0) << read_text(dir_ / "node.err");
  std::this_thread::sleep_for(200ms);
  take();

  // No DOA from inside the gap (a frame may straddle its edges: 0.1 s of margin).
  int before = 0, inside = 0, after = 0;
  for (double t : doa_times) {
    if (t < kGapFrom_s) ++before;
    if (t > kGapFrom_s + 0.1 && t < kGapTo_s - 0.1) ++inside;
    if (t > kGapTo_s) ++after;
  }
  std::printf("DOAs: %d before the gap, %d inside, %d after\n", before, inside, after);
  EXPECT_GT(before, 20) << read_text(dir_ / "node.err");
  EXPECT_EQ(inside, 0);
  EXPECT_GT(after, 20) << read_text(dir_ / "node.err");
  // NodeStatus: 0 dropouts before the gap, exactly one (one stretch) from inside it on.
  ASSERT_FALSE(dropouts.empty());
  for (const auto& [t, count] : dropouts) {
    if (t <= kGapFrom_s) {
      EXPECT_EQ(count, 0) << "t " << t;
    } else if (t >= kGapFrom_s + 1.0) {
      EXPECT_EQ(count, 1) << "t " << t;
    }
  }
  EXPECT_GE(dropouts.back().first, 13.0);
}

TEST_F(DdsFaults, RestartedFusionResumesTracksWithoutReusingIds) {
  dds::Participant participant(kFusionRestartDomain);
  TrackListener tracks(participant);
  const std::string id_file = (dir_ / "track-ids").string();
  auto first = fusion(kFusionRestartDomain, "fusion-1", {"--track-ids", id_file});
  const double epoch = std::floor(unix_now_s()) + 3.0;
  auto n1 = node("N1", epoch, kFusionRestartDomain, "N1");
  auto n2 = node("N2", epoch, kFusionRestartDomain, "N2");
  auto n3 = node("N3", epoch, kFusionRestartDomain, "N3");

  // A crash (SIGKILL: nothing flushed, nothing said) once the track is confirmed.
  auto confirmed_after = [&](std::size_t from) {
    return std::any_of(tracks.received.begin() + static_cast<std::ptrdiff_t>(from),
                       tracks.received.end(), [](auto& s) { return s.status == 1; });
  };
  tracks.collect(epoch + 12.0, [&] { return confirmed_after(0); });
  ASSERT_TRUE(confirmed_after(0)) << read_text(dir_ / "fusion-1.err");
  tracks.collect_until(unix_now_s() + 1.0);
  first->signal(SIGKILL);
  first->wait_exit(5s);
  const std::size_t before_restart = tracks.received.size();
  const double restarted_unix_s = unix_now_s();
  auto second = fusion(kFusionRestartDomain, "fusion-2", {"--track-ids", id_file});
  // Tracks resume: a confirmed track from the new instance within 8 s (its first DOAs, the
  // reorder window, M of N confirmation: ~2 s on an idle machine).
  tracks.collect(restarted_unix_s + 8.0, [&] { return confirmed_after(before_restart); });
  const double resumed_s = unix_now_s() - restarted_unix_s;
  tracks.collect_until(unix_now_s() + 1.0);
  for (auto* process : {n1.get(), n2.get(), n3.get()}) stop(*process, dir_ / "N1.err");
  stop(*second, dir_ / "fusion-2.err");

  std::set<dds_instance_handle_t> first_writers;
  std::set<int> first_ids, second_ids;
  for (std::size_t i = 0; i < before_restart; ++i) {
    first_writers.insert(tracks.received[i].writer);
    first_ids.insert(tracks.received[i].id);
  }
  for (std::size_t i = before_restart; i < tracks.received.size(); ++i) {
    if (first_writers.count(tracks.received[i].writer)) continue;  // the first's last samples
    second_ids.insert(tracks.received[i].id);
  }
  std::printf(
      "first instance: ids %d..%d; second: ids %d..%d; confirmed track %.2f s after "
      "the restart\n",
      *first_ids.begin(), *first_ids.rbegin(), second_ids.empty() ? 0 : *second_ids.begin(),
      second_ids.empty() ? 0 : *second_ids.rbegin(), resumed_s);
  EXPECT_TRUE(confirmed_after(before_restart)) << read_text(dir_ / "fusion-2.err");
  ASSERT_FALSE(second_ids.empty());
  // Every id of the second instance lies above every id the first could have published.
  EXPECT_GT(*second_ids.begin(), *first_ids.rbegin());
  for (int id : second_ids) EXPECT_EQ(first_ids.count(id), 0U) << id;
  EXPECT_EQ(first_writers.size(), 1U);
}

}  // namespace
