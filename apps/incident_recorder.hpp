#pragma once
// Incident capture (issue 19; docs/deployment.md "Incident recordings"): every array's raw audio
// goes through a bounded on-disk ring (capture/disk_audio_ring.hpp); on every zone alert (or a
// request) a clip from incident.before_s before the alert to incident.after_s after it is saved
// per array as DIRECTORY/<utc>-<zone>-track<id>/<array>.wav with its time sidecar
// (capture/recording_time.hpp), plus the DOA and track lines of that window (doa.jsonl,
// tracks.jsonl), the alert line (alert.json) and, when every array of the site is recorded, a
// site.json that replays the clips (`dronetrack replay DIR/site.json`).
//
// Clips start on a whole second of stream time, so the replayed clip's analysis frames and
// output ticks fall where the original run's did. A clip directory appears whole (written as
// NAME.partial, then renamed). Write errors (ring or clip: a full disk) are logged once each,
// counted for NodeStatus, and never stop the node.
//
// Threads: on_audio() runs on each array's node thread (one array's ring per thread); everything
// else on the thread that runs the fusion, while no node is reading (replay's lock step).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "apps/array_node.hpp"
#include "apps/fusion_observer.hpp"
#include "apps/line_history.hpp"
#include "capture/disk_audio_ring.hpp"
#include "config/site_config.hpp"

namespace dronetrack::apps {

struct IncidentArray {
  int site_index = 0;
  double sample_rate_hz = 0.0;
  int channels = 0;  // one per mic (the channel map applied)
};

// The stream the clips are cut from.
struct IncidentClock {
  std::int64_t utc_start_unix_ns = 0;  // wall-clock time of stream t = 0
  std::string clock = "system";        // as capture::RecordingTime::clock
  // The fusion feeds this recorder (replay): a clip waits for the fusion to pass its end, so its
  // track lines are complete. Without (a node): a clip waits for its audio only.
  bool with_fusion = true;
};

class IncidentRecorder : public FusionObserver, public AudioTap {
 public:
  // Creates DIRECTORY and one ring per array in DIRECTORY/ring/. Throws std::runtime_error.
  IncidentRecorder(const config::SiteConfig& site, std::vector<IncidentArray> arrays,
                   IncidentClock clock);
  ~IncidentRecorder() override;

  void on_audio(int array_index, const doa::AudioBlockView& block) override;
  void on_doa(const doa::DoaMeasurement& doa) override;
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) override;
  void on_zone_event(const fusion::ZoneEvent& event) override;
  void on_time(double time_s) override { fusion_time_s_ = time_s; }

  // Asks for a clip around stream time `time_s`; `label` names it, `event_line` is kept as
  // alert.json.
  void request(double time_s, const std::string& label, const std::string& event_line);
  // Saves every clip whose window has passed; all pending ones when `at_end`.
  void service(bool at_end);

  std::int64_t clips_saved() const { return clips_saved_; }
  // Failed clip writes plus the array's failed ring writes.
  std::int64_t write_errors(int site_index) const;
  // Sets the incident counters of `status` (its array_id names the array).
  void fill_status(doa::NodeStatus& status) const;

 private:
  struct Lane;
  struct Pending {
    double time_s = 0.0;
    std::string name;
    std::string event_line;
  };

  Lane* lane_of(int site_index) const;
  bool ready(const Pending& incident) const;
  void save(const Pending& incident);
  void write_clip(Lane& lane, const std::filesystem::path& folder, std::int64_t first_sample,
                  std::int64_t end_sample);
  static void write_lines(const std::filesystem::path& file, const LineHistory& lines,
                          double from_s, double to_s);
  void write_site(const std::filesystem::path& file) const;
  double history_s() const;

  const config::SiteConfig& site_;
  config::IncidentConfig settings_;
  IncidentClock clock_;
  std::vector<std::unique_ptr<Lane>> lanes_;
  std::vector<float> chunk_;  // one second of the widest array, for copying a clip out
  LineHistory doa_lines_;
  LineHistory track_lines_;
  char line_[2048];  // the longest DOA line is ~1 kB (jsonl_output.hpp)
  std::vector<Pending> pending_;
  double fusion_time_s_ = 0.0;
  std::int64_t clips_saved_ = 0;
  std::int64_t clip_errors_ = 0;
  std::int64_t requests_dropped_ = 0;
};

}  // namespace dronetrack::apps
