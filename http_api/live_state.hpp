#pragma once
// The picture the HTTP API serves: site layout, current tracks and their history, node health
// with each array's latest DOA, and alerts. Thread-safe: the fusion/replay thread publishes,
// the server's threads read snapshots. Publishing never blocks on a client: each streaming
// client has a bounded queue; a client whose queue is full is dropped, not waited for.
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"
#include "doa/node_status.hpp"
#include "fusion/fusion_params.hpp"
#include "fusion/track_report.hpp"
#include "fusion/zone_monitor.hpp"

namespace dronetrack::http_api {

struct SiteLayout {
  std::vector<doa::ArrayGeometry> arrays;
  std::vector<fusion::Zone> zones;
  double speed_of_sound_mps = 343.0;
};

struct LiveStateLimits {
  double history_window_s = 600.0;              // older track points (stream time) are dropped
  std::size_t history_points_per_track = 6000;  // 10 min at 10 Hz
  std::size_t max_alerts = 1000;                // the oldest alerts go first
  std::size_t stream_queue_events = 512;        // per streaming client; full: client dropped
  double stale_after_s = 3.0;                   // stream time without a NodeStatus: "stale"
  // A moving array's path (issue 15): a point each time it has moved this far or this long
  // since the last one; at most this many points (aged out with history_window_s).
  double path_point_spacing_m = 2.0;
  double path_point_interval_s = 5.0;
  std::size_t path_points_per_array = 600;
};

// One Server-Sent Event: "event: NAME\ndata: DATA\n\n" (DATA must be one line of JSON).
std::string sse_event(const std::string& name, const std::string& data);

// One streaming client's queue of ready-to-send Server-Sent Events. The publisher pushes,
// the client's server thread pops; neither waits for the other beyond a short lock.
class EventQueue {
 public:
  explicit EventQueue(std::size_t capacity) : capacity_(capacity) {}
  // Returns false (and marks the queue dropped) when the queue is full.
  bool push(std::shared_ptr<const std::string> event);
  // Appends all queued events to `out`; if there are none, first sleeps `timeout_ms` (the
  // reader polls: publishers never wake readers, which keeps a publish free of context
  // switches). False once dropped or closed.
  bool pop_all(std::vector<std::shared_ptr<const std::string>>& out, int timeout_ms);
  void close();
  bool dropped() const;

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::shared_ptr<const std::string>> events_;
  bool dropped_ = false;
  bool closed_ = false;
};

class LiveState {
 public:
  explicit LiveState(SiteLayout layout, LiveStateLimits limits = {});
  ~LiveState();
  LiveState(const LiveState&) = delete;
  LiveState& operator=(const LiveState&) = delete;

  // All live tracks at time_s (a track missing here is no longer current).
  void publish_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks);
  void publish_doa(const doa::DoaMeasurement& doa);  // latest kept per array and source_index
  void publish_node(const doa::NodeStatus& status);
  void publish_alert(const fusion::ZoneEvent& event);
  // Current stream time (seconds, same clock as the data). Never goes backwards.
  void set_time(double time_s);

  // JSON documents of the API (docs/http_api.md), each a consistent snapshot.
  std::string site_json() const;
  std::string tracks_json() const;
  std::string history_json(double since_s) const;
  std::string nodes_json() const;
  std::string alerts_json(double since_s) const;
  double time_s() const;

  // Streaming: a new client gets a queue primed with a snapshot (site time, tracks, nodes);
  // every publish then appends one event. `unsubscribe` is safe after a drop.
  std::shared_ptr<EventQueue> subscribe();
  void unsubscribe(const std::shared_ptr<EventQueue>& queue);
  std::size_t subscriber_count() const;
  std::int64_t dropped_clients() const;

 private:
  struct State;
  void broadcast(const std::string& event_name, std::string data);
  void record_pose(const doa::DoaMeasurement& doa);  // with mutex_ held

  const SiteLayout layout_;
  const LiveStateLimits limits_;
  std::unique_ptr<State> state_;  // guarded by mutex_
  mutable std::mutex mutex_;
  mutable std::mutex subscribers_mutex_;
  std::vector<std::shared_ptr<EventQueue>> subscribers_;
  std::int64_t dropped_clients_ = 0;  // guarded by subscribers_mutex_
};

}  // namespace dronetrack::http_api
