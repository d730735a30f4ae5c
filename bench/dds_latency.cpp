// End-to-end latency and message rate of the distributed mode on loopback.
//
// Latency: three array nodes (real NodePipelines on a simulated 14 s perimeter pass, paced at
// real time), each a forked process, publish Doa/NodeStatus; a fusion (DdsFusionService) runs in
// another, so every sample crosses the loopback network twice (node -> fusion -> subscriber); a
// Track subscriber in the parent stamps each Track sample on arrival. A tick is released by the
// first audio block whose published time passes tick + reorder window; the latency of a Track
// sample is its arrival minus the wall time at which that block's last sample was due (its "end of
// audio frame"). The reorder window itself (0.3 s, a deliberate wait) is reported separately.
//
// Rate: a writer publishes Doa samples as fast as it can to a reader in a forked child for 2 s.
//
// Each figure twice, plain DDS and then DDS Security (issue 18) as a secure site runs it: a PKI
// made by scripts/site-pki.sh, every participant authenticated with its own identity (a node's
// samples in its array's partition, the fusion reading "array.*" and checking each sample's
// partition, the subscriber with a subscriber's permissions), discovery and data encrypted.
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
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "apps/array_node.hpp"
#include "apps/dds_fusion_service.hpp"
#include "apps/dds_support.hpp"
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

// Plain DDS, or a secure site's PKI (a directory made by scripts/site-pki.sh).
struct Mode {
  const char* name = "plain";
  std::optional<fs::path> pki;
  std::optional<dds::SecurityFiles> identity(const std::string& name_in_pki) const {
    if (!pki) return std::nullopt;
    config::SiteConfig site;
    site.dds.security_directory = *pki;
    return apps::security_files(site, name_in_pki);
  }
};

// Each identity's participant, with or without security.
dds::Participant participant_for(const Mode& mode, int domain, const std::string& identity) {
  const auto security = mode.identity(identity);
  return dds::Participant(domain, security ? &*security : nullptr);
}

// One array node's DDS side: its own participant (identity) and writers, in its array's
// partition on a secure site.
struct NodeEndpoint {
  NodeEndpoint(const Mode& mode, const std::string& array_id)
      : participant(participant_for(mode, kLatencyDomain, array_id)),
        doa_topic(participant),
        status_topic(participant),
        doa_writer(participant, doa_topic, qos(mode, array_id, dds::doa_writer_qos)),
        status_writer(participant, status_topic, qos(mode, array_id, dds::status_writer_qos)) {}
  static dds::Qos qos(const Mode& mode, const std::string& array_id, void (*fill)(dds::Qos&)) {
    dds::Qos result;
    fill(result);
    if (mode.pki) result.partitions({dds::array_partition(array_id)});
    return result;
  }
  dds::Participant participant;
  dds::Topic<dronetrack_Doa> doa_topic;
  dds::Topic<dronetrack_NodeStatus> status_topic;
  dds::Writer<dronetrack_Doa> doa_writer;
  dds::Writer<dronetrack_NodeStatus> status_writer;
};

double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return std::nan("");
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(fraction * static_cast<double>(values.size() - 1));
  return values[index];
}

void run_fusion_child(const Mode& mode, const config::SiteConfig& site, double seconds) {
  dds::Participant participant = participant_for(mode, kLatencyDomain, "fusion");
  apps::FusionServiceOptions options;
  options.array_partitions = mode.pki.has_value();
  apps::DdsFusionService service(site, participant, {}, options);
  const auto end = SteadyClock::now() + std::chrono::duration<double>(seconds);
  while (SteadyClock::now() < end) service.poll(20ms);
  std::_Exit(0);
}

// The time of 10 ms block k (its last sample due) after `start`.
SteadyClock::time_point block_due(SteadyClock::time_point start, std::size_t block) {
  return start + std::chrono::duration_cast<SteadyClock::duration>(
                     std::chrono::duration<double>(0.01 * static_cast<double>(block + 1)));
}

// One array node in its own process, as on a site (and Cyclone's security plugins hold one
// identity per process): its recording paced at real time from `start`, DOAs and status
// published; at the end it writes to `report`, per 10 ms block, the newest time it had published
// by the end of that block.
[[noreturn]] void run_node_child(const Mode& mode, const config::SiteConfig& site, int index,
                                 SteadyClock::time_point start, std::size_t block_count,
                                 int report) {
  NodeEndpoint endpoint(mode, site.arrays[static_cast<std::size_t>(index)].geometry.id);
  endpoint.doa_writer.wait_for_readers(1, 10s);
  const auto& array = site.arrays[static_cast<std::size_t>(index)];
  apps::ArrayNode node(site, index, apps::open_recording(array, array.recording, 0.01));
  std::vector<double> published(block_count, 0.0);
  std::vector<doa::DoaMeasurement> doas;
  doa::NodeStatus status;
  dronetrack_Doa doa_sample{};
  dronetrack_NodeStatus status_sample{};
  double newest_published_s = 0.0;
  for (std::size_t block = 0; block < block_count; ++block) {
    std::this_thread::sleep_until(block_due(start, block));
    const double stream_s = 0.01 * static_cast<double>(block + 1);
    while (node.time_s() < stream_s - 1e-9 && node.step(doas)) {
    }
    for (const auto& measurement : doas) {
      dds::to_idl(measurement, 0, doa_sample);
      endpoint.doa_writer.try_write(doa_sample);
      newest_published_s = std::max(newest_published_s, measurement.time_s);
    }
    doas.clear();
    if (node.status_due(status)) {
      dds::to_idl(status, dds::seconds_to_ns(status.time_s), status_sample);
      endpoint.status_writer.try_write(status_sample);
      newest_published_s = std::max(newest_published_s, status.time_s);
    }
    published[block] = newest_published_s;
  }
  const auto* bytes = reinterpret_cast<const char*>(published.data());
  std::size_t left = published.size() * sizeof(double);
  while (left > 0) {
    const ssize_t written = write(report, bytes, left);
    if (written <= 0) break;
    bytes += written;
    left -= static_cast<std::size_t>(written);
  }
  std::_Exit(0);
}

// Reads a node child's report; false if it ended early.
bool read_report(int report, std::vector<double>& published) {
  auto* bytes = reinterpret_cast<char*>(published.data());
  std::size_t left = published.size() * sizeof(double);
  while (left > 0) {
    const ssize_t got = read(report, bytes, left);
    if (got <= 0) return false;
    bytes += got;
    left -= static_cast<std::size_t>(got);
  }
  return true;
}

int latency(const Mode& mode, const fs::path& scene_dir, double scene_s) {
  std::vector<std::string> warnings;
  const config::SiteConfig site = config::load_site_config(scene_dir / "site.json", warnings);
  const auto block_count = static_cast<std::size_t>(std::floor(scene_s / 0.01 + 1e-9));
  // Every process is forked before any DDS entity exists (each gets its own Cyclone instance);
  // the nodes start their audio together, after discovery (and, secure, the handshakes).
  const auto start = SteadyClock::now() + 4s;
  std::vector<pid_t> children;
  const pid_t fusion = fork();
  if (fusion == 0) run_fusion_child(mode, site, scene_s + 8.0);
  children.push_back(fusion);
  std::vector<int> reports;
  for (std::size_t i = 0; i < site.arrays.size(); ++i) {
    int report[2];
    if (pipe(report) != 0) return 1;
    const pid_t node = fork();
    if (node == 0) {
      close(report[0]);
      run_node_child(mode, site, static_cast<int>(i), start, block_count, report[1]);
    }
    close(report[1]);
    children.push_back(node);
    reports.push_back(report[0]);
  }
  auto stop_children = [&]() {
    for (pid_t child : children) kill(child, SIGTERM);
    for (pid_t child : children) waitpid(child, nullptr, 0);
    for (int report : reports) close(report);
  };

  dds::Participant participant = participant_for(mode, kLatencyDomain, "alert");
  dds::Topic<dronetrack_Track> track_topic(participant);
  dds::Qos track_qos;
  dds::track_reader_qos(track_qos);
  dds::Reader<dronetrack_Track> track_reader(participant, track_topic, track_qos);
  if (!track_reader.wait_for_writers(1, 10s)) {
    std::fprintf(stderr, "dds_latency (%s): the fusion child did not appear\n", mode.name);
    stop_children();
    return 1;
  }
  // Each Track sample: its tick and when it arrived; matched to the releasing block at the end.
  struct Arrival {
    double tick_s;
    SteadyClock::time_point arrived;
  };
  std::vector<Arrival> arrivals;
  arrivals.reserve(8192);
  const auto end = block_due(start, block_count) + 1s;
  while (SteadyClock::now() < end) {
    track_reader.wait(50ms);
    for (;;) {
      dds::Samples<dronetrack_Track> samples = track_reader.take();
      if (samples.empty()) break;
      const auto arrived = SteadyClock::now();
      for (std::size_t i = 0; i < samples.size(); ++i) {
        if (samples.info(i).valid_data) {
          arrivals.push_back({dds::ns_to_seconds(samples.data(i).time_ns), arrived});
        }
      }
    }
  }
  // The newest time any node had published by the end of each block.
  std::vector<double> newest(block_count, 0.0), published(block_count);
  for (int report : reports) {
    if (!read_report(report, published)) {
      std::fprintf(stderr, "dds_latency (%s): a node child ended early\n", mode.name);
      stop_children();
      return 1;
    }
    for (std::size_t block = 0; block < block_count; ++block) {
      newest[block] = std::max(newest[block], published[block]);
    }
  }
  // A tick is released by the first block whose published time passes tick + reorder window.
  const double window_s = site.fusion.reorder_window_s;
  std::vector<double> latencies_ms;
  for (const Arrival& arrival : arrivals) {
    const auto releasing = std::find_if(newest.begin(), newest.end(), [&](double published_s) {
      return published_s >= arrival.tick_s + window_s - 1e-9;
    });
    if (releasing == newest.end()) continue;
    const auto block = static_cast<std::size_t>(releasing - newest.begin());
    latencies_ms.push_back(
        std::chrono::duration<double, std::milli>(arrival.arrived - block_due(start, block))
            .count());
  }
  const auto tracks_received = static_cast<long long>(arrivals.size());
  stop_children();
  std::printf(
      "dds_latency (%s): end of audio frame -> Track at subscriber (node -> fusion -> "
      "subscriber, 2 loopback hops): p50 %.2f ms, p99 %.2f ms, max %.2f ms over %zu "
      "Track samples (%lld received)\n",
      mode.name, percentile(latencies_ms, 0.5), percentile(latencies_ms, 0.99),
      percentile(latencies_ms, 1.0), latencies_ms.size(), static_cast<long long>(tracks_received));
  if (mode.pki) return latencies_ms.empty() ? 1 : 0;
  std::printf(
      "dds_latency: plus the deliberate reorder window of %.2f s and half an analysis "
      "frame (%.3f s) between a Track's time and the audio that releases it\n",
      window_s, site.doa.frame_s / 2.0);
  return 0;
}

// On a secure site the writer is node N1's identity in its partition (a node may write only its
// own array's samples), the reader the fusion's, in the domain the site's governance names (the
// latency run's, over by now).
int rate(const Mode& mode) {
  const int domain = mode.pki ? kLatencyDomain : kRateDomain;
  int ready[2];
  if (pipe(ready) != 0) return 1;
  const pid_t child = fork();
  if (child == 0) {
    dds::Participant participant = participant_for(mode, domain, "fusion");
    dds::Topic<dronetrack_Doa> topic(participant);
    dds::Qos qos;
    dds::doa_reader_qos(qos);
    if (mode.pki) qos.partitions({dds::array_partition("*")});
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
  dds::Participant participant = participant_for(mode, domain, "N1");
  dds::Topic<dronetrack_Doa> topic(participant);
  dds::Writer<dronetrack_Doa> writer(participant, topic,
                                     NodeEndpoint::qos(mode, "N1", dds::doa_writer_qos));
  writer.wait_for_readers(1, 10s);
  doa::DoaMeasurement measurement;
  measurement.pair_count = 6;
  dronetrack_Doa sample{};
  // Plain: three arrays' keys from one writer; secure: N1's only (its permissions).
  const char* ids[] = {"N1", mode.pki ? "N1" : "N2", mode.pki ? "N1" : "N3"};
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
      "dds_latency (%s): Doa samples (%zu bytes in memory), reliable, keep-last 64 per array, "
      "one writer -> one reader in another process: %.0f written/s, %.0f received/s\n",
      mode.name, sizeof(dronetrack_Doa), static_cast<double>(sent) / elapsed_s,
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
  const double run_s = std::min(scene_s, scenario.duration_s - 0.2);
  const Mode plain;
  int status = latency(plain, dir, run_s);
  if (status == 0) status = rate(plain);
  // The same with DDS Security: a PKI for this site's arrays, the fusion and a subscriber, in
  // both benchmark domains (the governance names the domains it governs).
  Mode secure{"secure", dir / "pki"};
  const std::string command = std::string("bash '") + DRONETRACK_SOURCE_DIR +
                              "/scripts/site-pki.sh' '" + secure.pki->string() +
                              "' --nodes N1,N2,N3 --domain " + std::to_string(kLatencyDomain) +
                              " > '" + (dir / "pki.log").string() + "' 2>&1";
  if (status == 0 && std::system(command.c_str()) != 0) {
    std::fprintf(stderr, "dds_latency: scripts/site-pki.sh failed (%s)\n",
                 (dir / "pki.log").c_str());
    status = 1;
  }
  if (status == 0) status = latency(secure, dir, run_s);
  if (status == 0) status = rate(secure);
  if (status == 0) fs::remove_all(dir);
  return status;
}
