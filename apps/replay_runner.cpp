#include "apps/replay_runner.hpp"

#include <algorithm>
#include <chrono>
#include <limits>
#include <thread>

#include "apps/array_node.hpp"
#include "apps/fusion_driver.hpp"
#include "capture/recording_info.hpp"
#include "common/log.hpp"

namespace dronetrack::apps {

ReplaySummary run_replay(const config::SiteConfig& site,
                         const std::vector<FusionObserver*>& observers,
                         const ReplayOptions& options, const std::atomic<bool>* stop) {
  using Clock = std::chrono::steady_clock;
  std::vector<ArrayNode> nodes;
  nodes.reserve(site.arrays.size());
  double total_s = 0.0;
  for (std::size_t i = 0; i < site.arrays.size(); ++i) {
    auto source = open_recording(site.arrays[i], site.arrays[i].recording, options.block_s);
    nodes.emplace_back(site, static_cast<int>(i), std::move(source));
  }
  for (const auto& array : site.arrays) {
    // Only for the progress line's denominator; reads the header alone.
    const capture::RecordingInfo info = capture::probe_recording(array.recording);
    total_s = std::max(total_s, static_cast<double>(info.frames) / info.sample_rate_hz);
  }
  if (options.max_duration_s > 0.0) total_s = std::min(total_s, options.max_duration_s);

  FusionDriver driver(site, observers);
  ReplaySummary summary;
  std::vector<bool> active(nodes.size(), true);
  std::vector<doa::DoaMeasurement> doas;
  doas.reserve(256);
  doa::NodeStatus status;
  const auto wall_start = Clock::now();
  auto next_progress = wall_start + std::chrono::seconds(3);
  double target_s = 0.0;

  while (std::any_of(active.begin(), active.end(), [](bool is_active) { return is_active; })) {
    if (stop && stop->load()) break;
    target_s += options.block_s;
    if (options.max_duration_s > 0.0 && target_s > options.max_duration_s + 1e-9) break;
    double slowest_s = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      if (!active[i]) continue;
      while (nodes[i].time_s() < target_s - 1e-9) {
        if (!nodes[i].step(doas)) {
          active[i] = false;
          log::info("replay: ", nodes[i].array_id(), " recording ended at ", nodes[i].time_s(),
                    " s");
          break;
        }
      }
      if (nodes[i].status_due(status)) driver.on_node_status(status);
      if (active[i]) slowest_s = std::min(slowest_s, nodes[i].time_s());
    }
    for (const auto& doa : doas) {
      ++summary.doas;
      if (driver.on_doa(doa) == fusion::DoaVerdict::accepted) ++summary.doas_accepted;
    }
    doas.clear();
    if (std::isfinite(slowest_s)) {
      driver.advance_to(slowest_s);
      summary.stream_s = std::max(summary.stream_s, slowest_s);
    }
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
  driver.finish();
  summary.ticks = driver.ticks_emitted();
  summary.wall_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
  return summary;
}

}  // namespace dronetrack::apps
