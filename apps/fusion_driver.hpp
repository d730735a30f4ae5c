#pragma once
// Drives a FusionEngine from a stream of DOAs: feeds them, runs the engine up to the current
// stream time, and emits track reports at the output rate plus zone events. Shared by
// `replay` (in-process) and `fusion` (DDS), so both paths produce the same outputs.
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "apps/fusion_observer.hpp"
#include "config/site_config.hpp"
#include "doa/node_status.hpp"
#include "fusion/fusion_engine.hpp"
#include "fusion/zone_monitor.hpp"

namespace dronetrack::apps {

// The warning line for a swap the fusion named on a mirror-symmetric array (issue 16,
// fusion/array_mirror_check.hpp), naming the array and both channels, e.g. "A2 channel 1: swapped
// with channel 2 (seen by the fusion): ...". `input_a`/`input_b`: the two mics' input channels
// (named when a channel_map moved them).
std::string mirror_swap_warning(const std::string& array_id, int input_a, int input_b,
                                const fusion::MirrorSwapEvent& event);

class FusionDriver {
 public:
  FusionDriver(const config::SiteConfig& site, std::vector<FusionObserver*> observers);

  // Returns the engine's verdict; rejected DOAs are counted by the engine and not forwarded.
  fusion::DoaVerdict on_doa(const doa::DoaMeasurement& doa);
  // Forwarded with the swaps the fusion found on that array (issue 16) set in its channels'
  // array problems, so /api/nodes and the page show them beside the node's own checks.
  void on_node_status(const doa::NodeStatus& status);
  // Sets the `swapped` flags the fusion's mirror check holds for status's array.
  void mark_fusion_findings(doa::NodeStatus& status) const;
  // The stream has reached now_s: every output tick up to now_s - reorder window is emitted.
  void advance_to(double now_s);
  // End of stream: emits the remaining ticks up to the last time seen, or up to heard_until_s
  // when later: the end of the audio the nodes analysed (a replay of recordings). The last DOA
  // is stamped a node's output latency (half a frame and the per-source regression's delay,
  // ~0.3 s) before the audio it was made from ends, and a live fusion would go on reporting
  // the tracks over those last moments; a DOA file knows no such end (docs/fusion.md).
  void finish(double heard_until_s = -std::numeric_limits<double>::infinity());

  const fusion::FusionEngine& engine() const { return engine_; }
  // False when no observer wants tracks: DOAs are then only checked (FusionEngine::admit), no
  // tracker runs and no tick is emitted.
  bool tracking() const { return tracking_; }
  std::int64_t ticks_emitted() const { return ticks_emitted_; }

 private:
  void emit_tick(double tick_s);
  // Logs the swaps the engine named since the last call (one warning line each).
  void report_mirror_swaps();

  fusion::FusionEngine engine_;
  fusion::ZoneMonitor zones_;
  std::vector<FusionObserver*> observers_;
  bool tracking_;
  double output_period_s_;
  double reorder_window_s_;
  double next_tick_s_ = 0.0;
  double latest_time_s_ = 0.0;
  // Ticks are multiples of the output period from the stream's start, not from t = 0: a DOA
  // file on another clock (seconds since 1970) must not mean 17 billion empty ticks first.
  std::int64_t first_tick_index_ = -1;
  std::int64_t ticks_emitted_ = 0;
  std::vector<fusion::TrackReport> tracks_;     // reused every tick
  std::vector<fusion::ZoneEvent> zone_events_;  // reused every tick
  std::vector<std::string> array_ids_;
  std::vector<std::vector<int>> channel_maps_;
  std::vector<fusion::MirrorSwapEvent> mirror_events_;
  // Per array, per channel: swapped said by the fusion at any time so far.
  std::vector<std::vector<doa::ArrayFlags>> swapped_seen_;
};

}  // namespace dronetrack::apps
