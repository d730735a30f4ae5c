#include "apps/replay_runner.hpp"

#include <algorithm>
#include <barrier>
#include <chrono>
#include <ctime>
#include <limits>
#include <string>
#include <thread>

#include "apps/array_node.hpp"
#include "apps/fusion_driver.hpp"
#include "apps/incident_recorder.hpp"
#include "common/log.hpp"

namespace dronetrack::apps {
namespace {

// Taken during static initialisation, before main(): the first-frame line then counts all the
// start-up (site read, recordings opened, nodes built, FFTs planned), as an operator sees it.
const std::chrono::steady_clock::time_point process_start = std::chrono::steady_clock::now();

// One array node and what it produced during the current step.
struct NodeLane {
  explicit NodeLane(ArrayNode array_node) : node(std::move(array_node)) { doas.reserve(64); }

  void advance(double target_s) {
    status_ready = false;
    ended_now = false;
    if (!active) return;
    while (node.time_s() < target_s - 1e-9) {
      if (!node.step(doas)) {
        active = false;
        ended_now = true;
        break;
      }
    }
    status_ready = node.status_due(status);
  }

  ArrayNode node;
  std::vector<doa::DoaMeasurement> doas;
  doa::NodeStatus status;
  bool active = true;
  bool ended_now = false;
  bool status_ready = false;
};

// Advances every lane to the same stream time, spreading lanes over worker threads. The nodes
// are independent until the fusion, so this is where a replay uses more than one core.
class LaneRunner {
 public:
  LaneRunner(std::vector<NodeLane>& lanes, unsigned threads)
      : lanes_(lanes),
        thread_count_(
            std::max(1u, std::min<unsigned>(threads, static_cast<unsigned>(lanes.size())))),
        start_(thread_count_),
        done_(thread_count_) {
    for (unsigned worker = 1; worker < thread_count_; ++worker) {
      workers_.emplace_back([this, worker] { work(worker); });
    }
  }
  ~LaneRunner() {
    stopping_ = true;
    if (thread_count_ > 1) start_.arrive_and_wait();
  }
  LaneRunner(const LaneRunner&) = delete;
  LaneRunner& operator=(const LaneRunner&) = delete;

  void advance_all(double target_s) {
    target_s_ = target_s;
    if (thread_count_ > 1) start_.arrive_and_wait();
    advance_share(0);
    if (thread_count_ > 1) done_.arrive_and_wait();
  }

 private:
  void work(unsigned worker) {
    for (;;) {
      start_.arrive_and_wait();
      if (stopping_) return;
      advance_share(worker);
      done_.arrive_and_wait();
    }
  }
  void advance_share(unsigned worker) {
    for (std::size_t i = worker; i < lanes_.size(); i += thread_count_)
      lanes_[i].advance(target_s_);
  }

  std::vector<NodeLane>& lanes_;
  const unsigned thread_count_;
  std::barrier<> start_;
  std::barrier<> done_;
  double target_s_ = 0.0;  // written before start_, read after it (the barrier orders them)
  bool stopping_ = false;  // likewise
  std::vector<std::jthread> workers_;
};

}  // namespace

ReplaySummary run_replay(const config::SiteConfig& site,
                         const std::vector<FusionObserver*>& observers,
                         const ReplayOptions& options, const std::atomic<bool>* stop) {
  using Clock = std::chrono::steady_clock;
  std::vector<NodeLane> lanes;
  lanes.reserve(site.arrays.size());
  double total_s = 0.0;
  for (std::size_t i = 0; i < site.arrays.size(); ++i) {
    const auto& array = site.arrays[i];
    auto recording = open_recording(array, array.recording, options.block_s);
    const std::int64_t start_sample =
        i < options.start_samples.size() ? options.start_samples[i] : 0;
    // Only for the progress line's denominator.
    total_s = std::max(total_s, static_cast<double>(recording->total_frames() + start_sample) /
                                    recording->sample_rate_hz());
    lanes.emplace_back(
        ArrayNode(site, static_cast<int>(i), std::move(recording), true, start_sample));
    if (options.incidents) lanes.back().node.set_audio_tap(options.incidents);
  }
  if (options.max_duration_s > 0.0) total_s = std::min(total_s, options.max_duration_s);

  FusionDriver driver(site, observers);
  if (!driver.tracking())
    log::info("replay: no output takes tracks: the DOAs are checked, the tracker does not run");
  ReplaySummary summary;
  const unsigned threads =
      options.threads > 0 ? options.threads : std::max(1u, std::thread::hardware_concurrency());
  LaneRunner runner(lanes, threads);
  const auto wall_start = Clock::now();
  if (options.on_start) options.on_start();
  auto next_progress = wall_start + std::chrono::seconds(3);
  double target_s = 0.0;
  bool first_frame_logged = false;

  while (
      std::any_of(lanes.begin(), lanes.end(), [](const NodeLane& lane) { return lane.active; })) {
    if (stop && stop->load()) break;
    target_s += options.block_s;
    if (options.max_duration_s > 0.0 && target_s > options.max_duration_s + 1e-9) break;
    runner.advance_all(target_s);
    if (!first_frame_logged && std::any_of(lanes.begin(), lanes.end(), [](const NodeLane& lane) {
          return lane.node.frames_processed() > 0;
        })) {
      first_frame_logged = true;
      // CPU time too: on a busy machine the wall time is mostly waiting for a core.
      log::info("replay: first frame analysed ",
                std::chrono::duration<double>(Clock::now() - process_start).count(),
                " s after the process started, ",
                static_cast<double>(std::clock()) / CLOCKS_PER_SEC, " s CPU");
    }

    // The in-process transport: the same messages a DDS fusion would receive, in array order.
    double slowest_s = std::numeric_limits<double>::infinity();
    for (auto& lane : lanes) {
      if (lane.ended_now) {
        log::info("replay: ", lane.node.array_id(), " recording ended at ", lane.node.time_s(),
                  " s, ", lane.node.frames_processed(), " frames analysed");
      }
      if (lane.status_ready) {
        if (options.incidents) options.incidents->fill_status(lane.status);
        driver.on_node_status(lane.status);
      }
      for (const auto& doa : lane.doas) {
        ++summary.doas;
        if (driver.on_doa(doa) == fusion::DoaVerdict::accepted) ++summary.doas_accepted;
      }
      lane.doas.clear();
      // The fusion may run up to the oldest time any node could still report a DOA for.
      if (lane.active) slowest_s = std::min(slowest_s, lane.node.settled_time_s());
    }
    if (std::isfinite(slowest_s)) {
      driver.advance_to(slowest_s);
      summary.stream_s = std::max(summary.stream_s, slowest_s);
    }
    // Between steps no node reads audio: the clips can be cut from the rings.
    if (options.incidents) options.incidents->service(false);
    if (options.realtime) {
      std::this_thread::sleep_until(wall_start + std::chrono::duration_cast<Clock::duration>(
                                                     std::chrono::duration<double>(target_s)));
    }
    if (options.progress && Clock::now() >= next_progress) {
      next_progress += std::chrono::seconds(3);
      const double wall_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
      log::info("replay: ", target_s, " / ", total_s, " s (",
                static_cast<int>(100.0 * target_s / std::max(total_s, 1e-9)), " %), ",
                target_s / std::max(wall_s, 1e-9), "x real time");
    }
  }
  for (const auto& lane : lanes) {
    summary.stream_s = std::max(summary.stream_s, lane.node.time_s());
    if (lane.node.source().cut_short() && summary.cut_short.empty())
      summary.cut_short = lane.node.source().describe() + " ended at " +
                          std::to_string(lane.node.time_s()) +
                          " s, before its header's end (truncated while being read)";
  }
  // Up to the end of the audio analysed: the last DOAs are stamped a node's latency before it.
  driver.finish(summary.stream_s);
  if (options.incidents) options.incidents->service(true);
  summary.ticks = driver.ticks_emitted();
  summary.counters = driver.engine().counters();
  summary.wall_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
  // Bad audio must not pass in silence: one line per array whose audio had problems.
  for (std::size_t a = 0; a < lanes.size(); ++a) {
    const NodeLane& lane = lanes[a];
    summary.nodes.push_back(lane.node.status());
    driver.mark_fusion_findings(summary.nodes.back());
    // The fusion's swap check on this array (issue 16): how near its bar it came.
    const fusion::MirrorCheckStatus& mirror = driver.engine().mirror_status(a);
    if (mirror.mirrors > 0)
      log::info("replay: ", lane.node.array_id(), " mirror check: ", mirror.evidence_doas,
                " evidence DOAs held, largest evidence ratio ", mirror.largest_ratio, " (bar ",
                site.fusion.mirror_check.evidence_ratio, "), last best swap ",
                mirror.best_channel_a, "-", mirror.best_channel_b, " at ", mirror.best_ratio,
                " over ", mirror.best_sectors, " sectors");
    if (options.incidents) options.incidents->fill_status(summary.nodes.back());
    if (const std::string problems = health_summary(summary.nodes.back()); !problems.empty())
      log::warn("replay: audio problems: ", problems);
  }
  return summary;
}

}  // namespace dronetrack::apps
