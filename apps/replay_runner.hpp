#pragma once
// `replay`: every array node and the fusion in one process over an in-process transport (the
// same message structs the DDS path carries), as fast as the CPU allows or paced at real time.
#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include "apps/fusion_observer.hpp"
#include "config/site_config.hpp"
#include "doa/node_status.hpp"
#include "fusion/fusion_engine.hpp"

namespace dronetrack::apps {

class IncidentRecorder;

struct ReplayOptions {
  bool realtime = false;        // pace at real time (for serving the page)
  double block_s = 0.05;        // audio read granularity; the nodes frame internally
  bool progress = true;         // a progress line on stderr every few seconds
  double max_duration_s = 0.0;  // stop after this much stream time (0: whole recordings)
  unsigned threads = 0;         // node threads (0: one per core)
  // Called once when stream time 0 is due on the wall clock (the metrics' latency clock).
  std::function<void()> on_start;
  // Per array (site order), the stream sample index of its recording's first sample
  // (apps/recording_alignment.hpp); empty: every recording starts at t = 0.
  std::vector<std::int64_t> start_samples;
  IncidentRecorder* incidents = nullptr;  // incident capture (also among the observers); or none
};

struct ReplaySummary {
  double stream_s = 0.0;  // longest recording time processed
  double wall_s = 0.0;
  std::int64_t doas = 0;  // produced by the nodes
  std::int64_t doas_accepted = 0;
  std::int64_t ticks = 0;
  fusion::FusionCounters counters;  // the engine's, at the end
  std::string cut_short;  // why the result is partial though the run finished ("" if whole)
  // Every array's status at the end, in site order: per-channel audio health over the run
  // (problems_seen, non-finite and clipped counts). run_replay logs one warning line per array
  // that had any problem (health_summary() in apps/array_node.hpp).
  std::vector<doa::NodeStatus> nodes;
};

// Throws on unreadable recordings (one line naming file and problem).
ReplaySummary run_replay(const config::SiteConfig& site,
                         const std::vector<FusionObserver*>& observers,
                         const ReplayOptions& options, const std::atomic<bool>* stop = nullptr);

}  // namespace dronetrack::apps
