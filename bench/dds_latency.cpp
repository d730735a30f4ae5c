// End-to-end latency and message rate of the distributed mode on loopback.
//
// Latency: three array nodes (real NodePipelines on a simulated 14 s perimeter pass, paced at
// real time) publish Doa/NodeStatus; a fusion (DdsFusionService) runs in a forked child process,
// so every sample crosses the loopback network twice (node -> fusion -> subscriber); a Track
// subscriber in the parent stamps each Track sample on arrival. A tick is released by the first
// audio block whose published time passes tick + reorder window; the latency of a Track sample
// is its arrival minus the wall time at which that block's last sample was due (its "end of
// audio frame"). The reorder window itself (0.3 s, a deliberate wait) is reported separately.
//
// Rate: a writer publishes Doa samples as fast as it can to a reader in a forked child for 2 s.
//
// Usage: dds_latency [seconds of scene, default 10]. Prints one line per figure.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <thread>
#include <vector>

#include "apps/array_node.hpp"
#include "apps/dds_fusion_service.hpp"
#include "config/site_config.hpp"
#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"
#include "sim/render.hpp"
#include "sim/scenario.hpp"

namespace {

using namespace dronetrack;
using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;
namespace fs = std::filesystem;

constexpr int kLatencyDomain = 141;
constexpr int kRateDomain = 142;

double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return std::nan("");
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(fraction * static_cast<double>(values.size() - 1));
  return values[index];
}

void run_fusion_child(const config::SiteConfig& site, double seconds) {
  dds::Participant participant(kLatencyDomain);
  apps::DdsFusionService service(site, participant, {});
  const auto end = SteadyClock::now() + std::chrono::duration<double>(seconds);
  while (SteadyClock::now() < end) service.poll(20ms);
  std::_Exit(0);
}

int latency(const fs::path& scene_dir, double scene_s) {
  std::vector<std::string> warnings;
  const config::SiteConfig site = config::load_site_config(scene_dir / "site.json", warnings);
  const pid_t child = fork();  // before any DDS entity: the child gets its own Cyclone instance
  if (child == 0) run_fusion_child(site, scene_s + 5.0);

  dds::Participant participant(kLatencyDomain);
  dds::Topic<dronetrack_Doa> doa_topic(participant);
  dds::Topic<dronetrack_NodeStatus> status_topic(participant);
  dds::Topic<dronetrack_Track> track_topic(participant);
  dds::Qos doa_qos, status_qos, track_qos;
  dds::doa_writer_qos(doa_qos);
  dds::status_writer_qos(status_qos);
  dds::track_reader_qos(track_qos);
  dds::Writer<dronetrack_Doa> doa_writer(participant, doa_topic, doa_qos);
  dds::Writer<dronetrack_NodeStatus> status_writer(participant, status_topic, status_qos);
  dds::Reader<dronetrack_Track> track_reader(participant, track_topic, track_qos);
  if (!doa_writer.wait_for_readers(1, 10s) || !track_reader.wait_for_writers(1, 10s)) {
    std::fprintf(stderr, "dds_latency: the fusion child did not appear\n");
    return 1;
  }

  std::vector<apps::ArrayNode> nodes;
  for (std::size_t i = 0; i < site.arrays.size(); ++i) {
    nodes.emplace_back(site, static_cast<int>(i),
                       apps::open_recording(site.arrays[i], site.arrays[i].recording, 0.01));
  }
  // Per audio block: when its last sample was due, and the newest time published after it.
  struct Block {
    SteadyClock::time_point due;
    double published_s;
  };
  std::vector<Block> blocks;
  blocks.reserve(4096);
  std::vector<double> latencies_ms;
  std::vector<doa::DoaMeasurement> doas;
  doa::NodeStatus status;
  dronetrack_Doa doa_sample{};
  dronetrack_NodeStatus status_sample{};
  double newest_published_s = 0.0;
  std::int64_t tracks_received = 0;
  const double window_s = site.fusion.reorder_window_s;

  auto drain_tracks = [&]() {
    for (;;) {
      dds::Samples<dronetrack_Track> samples = track_reader.take();
      if (samples.empty()) return;
      const auto arrived = SteadyClock::now();
      for (std::size_t i = 0; i < samples.size(); ++i) {
        if (!samples.info(i).valid_data) continue;
        ++tracks_received;
        const double tick_s = dds::ns_to_seconds(samples.data(i).time_ns);
        const auto releasing = std::find_if(blocks.begin(), blocks.end(), [&](const Block& block) {
          return block.published_s >= tick_s + window_s - 1e-9;
        });
        if (releasing == blocks.end()) continue;
        latencies_ms.push_back(
            std::chrono::duration<double, std::milli>(arrived - releasing->due).count());
      }
    }
  };

  const auto start = SteadyClock::now() + 200ms;
  for (double stream_s = 0.01; stream_s <= scene_s + 1e-9; stream_s += 0.01) {
    const auto due = start + std::chrono::duration_cast<SteadyClock::duration>(
                                 std::chrono::duration<double>(stream_s));
    std::this_thread::sleep_until(due);
    for (auto& node : nodes) {
      while (node.time_s() < stream_s - 1e-9 && node.step(doas)) {
      }
      for (const auto& measurement : doas) {
        dds::to_idl(measurement, 0, doa_sample);
        doa_writer.try_write(doa_sample);
        newest_published_s = std::max(newest_published_s, measurement.time_s);
      }
      doas.clear();
      if (node.status_due(status)) {
        dds::to_idl(status, dds::seconds_to_ns(status.time_s), status_sample);
        status_writer.try_write(status_sample);
        newest_published_s = std::max(newest_published_s, status.time_s);
      }
    }
    blocks.push_back({due, newest_published_s});
    drain_tracks();
  }
  const auto tail_end = SteadyClock::now() + 1s;
  while (SteadyClock::now() < tail_end) {
    track_reader.wait(50ms);
    drain_tracks();
  }
  kill(child, SIGTERM);
  waitpid(child, nullptr, 0);
  std::printf(
      "dds_latency: end of audio frame -> Track at subscriber (node -> fusion -> "
      "subscriber, 2 loopback hops): p50 %.2f ms, p99 %.2f ms, max %.2f ms over %zu "
      "Track samples (%lld received)\n",
      percentile(latencies_ms, 0.5), percentile(latencies_ms, 0.99), percentile(latencies_ms, 1.0),
      latencies_ms.size(), static_cast<long long>(tracks_received));
  std::printf(
      "dds_latency: plus the deliberate reorder window of %.2f s and half an analysis "
      "frame (%.3f s) between a Track's time and the audio that releases it\n",
      window_s, site.doa.frame_s / 2.0);
  return 0;
}

int rate() {
  int ready[2];
  if (pipe(ready) != 0) return 1;
  const pid_t child = fork();
  if (child == 0) {
    dds::Participant participant(kRateDomain);
    dds::Topic<dronetrack_Doa> topic(participant);
    dds::Qos qos;
    dds::doa_reader_qos(qos);
    dds::Reader<dronetrack_Doa> reader(participant, topic, qos);
    reader.wait_for_writers(1, 10s);
    std::int64_t received = 0;
    const auto end = SteadyClock::now() + 3s;
    while (SteadyClock::now() < end) {
      if (!reader.wait(50ms)) continue;
      dds::Samples<dronetrack_Doa> samples = reader.take();
      received += static_cast<std::int64_t>(samples.size());
    }
    (void)!write(ready[1], &received, sizeof received);
    std::_Exit(0);
  }
  dds::Participant participant(kRateDomain);
  dds::Topic<dronetrack_Doa> topic(participant);
  dds::Qos qos;
  dds::doa_writer_qos(qos);
  dds::Writer<dronetrack_Doa> writer(participant, topic, qos);
  writer.wait_for_readers(1, 10s);
  doa::DoaMeasurement measurement;
  measurement.pair_count = 6;
  dronetrack_Doa sample{};
  const char* ids[] = {"N1", "N2", "N3"};
  std::int64_t sent = 0;
  const auto begin = SteadyClock::now();
  const auto end = begin + 2s;
  while (SteadyClock::now() < end) {
    for (int k = 0; k < 100; ++k) {
      measurement.array_id = ids[sent % 3];
      measurement.time_s = static_cast<double>(sent) * 1e-3;
      dds::to_idl(measurement, 0, sample);
      if (writer.try_write(sample) >= 0) ++sent;
    }
  }
  const double elapsed_s = std::chrono::duration<double>(SteadyClock::now() - begin).count();
  std::int64_t received = 0;
  (void)!read(ready[0], &received, sizeof received);
  waitpid(child, nullptr, 0);
  std::printf(
      "dds_latency: Doa samples (%zu bytes in memory), reliable, keep-last 64 per array, "
      "one writer -> one reader in another process: %.0f written/s, %.0f received/s\n",
      sizeof(dronetrack_Doa), static_cast<double>(sent) / elapsed_s,
      static_cast<double>(received) / elapsed_s);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const double scene_s = argc > 1 ? std::atof(argv[1]) : 10.0;
  if (!std::getenv("CYCLONEDDS_URI")) {
    const std::string uri =
        std::string("file://") + DRONETRACK_SOURCE_DIR + "/config/cyclonedds-loopback.xml";
    setenv("CYCLONEDDS_URI", uri.c_str(), 1);
  }
  const fs::path dir =
      fs::temp_directory_path() / ("dronetrack-dds-bench-" + std::to_string(getpid()));
  std::vector<std::string> warnings;
  sim::Scenario scenario = sim::load_scenario(
      fs::path(DRONETRACK_SOURCE_DIR) / "tests/dds/perimeter-short.json", warnings);
  scenario.duration_s = std::min(scenario.duration_s, scene_s + 0.5);
  for (auto& end_s : scenario.recording_end_s) {
    if (end_s >= scenario.duration_s) end_s = 0.0;
  }
  sim::write_scene(scenario, dir);
  int status = latency(dir, std::min(scene_s, scenario.duration_s - 0.2));
  if (status == 0) status = rate();
  fs::remove_all(dir);
  return status;
}
