#pragma once
// JSON-lines outputs of SPEC 3.2 (DOAs, tracks, alerts) as fusion observers writing to an
// OutputFile (a file committed when the run completes, a live log, or stdout).
// Formatted with snprintf into a reused buffer: this runs for every DOA of a long replay.
#include <cstdio>
#include <filesystem>
#include <string>

#include "apps/fusion_observer.hpp"
#include "common/output_file.hpp"

namespace dronetrack::apps {

// {"t":..,"array":"A1","direction":[..],"azimuth_deg":..,"elevation_deg":..,"quality":..,...}
int format_doa_line(const doa::DoaMeasurement& doa, char* buffer, std::size_t size);
// {"t":..,"id":..,"position_m":[..],"velocity_mps":[..],"acceleration_mps2":[..],
//  "position_std_m":[..],"status":"..","class":"..","class_confidence":..}
int format_track_line(double time_s, const fusion::TrackReport& track, char* buffer,
                      std::size_t size);

class DoaLinesWriter : public FusionObserver {
 public:
  explicit DoaLinesWriter(const std::filesystem::path& path,
                          OutputFile::Mode mode = OutputFile::Mode::replace)
      : out_(path, mode) {}
  OutputFile& output() { return out_; }
  bool wants_tracks() const override { return false; }
  void on_doa(const doa::DoaMeasurement& doa) override;

 private:
  OutputFile out_;
  char buffer_[2048];  // the longest line (cone peaks, pose, acoustic, 64-byte id) is ~1 kB
};

class TrackLinesWriter : public FusionObserver {
 public:
  explicit TrackLinesWriter(const std::filesystem::path& path,
                            OutputFile::Mode mode = OutputFile::Mode::replace)
      : out_(path, mode) {}
  OutputFile& output() { return out_; }
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) override;

 private:
  OutputFile out_;
  char buffer_[1024];
};

// {"t":..,"array":"A1","source":0,"direction":[..],"tdoa_s":[..]}: a full-rank DOA's pair
// delays (mic pairs i < j, lexicographic), for `calibrate --tdoa` (docs/calibration.md).
std::string format_tdoa_line(const doa::DoaMeasurement& doa);

class TdoaLinesWriter : public FusionObserver {
 public:
  explicit TdoaLinesWriter(const std::filesystem::path& path) : out_(path) {}
  OutputFile& output() { return out_; }
  bool wants_tracks() const override { return false; }
  void on_doa(const doa::DoaMeasurement& doa) override;

 private:
  OutputFile out_;
};

// {"t":..,"zone":"..","track_id":..,"event":"entered|left|class_changed","class":"..",
//  ["previous_class":"..",] "position_m":[..]}
int format_alert_line(const fusion::ZoneEvent& event, char* buffer, std::size_t size);

class AlertLinesWriter : public FusionObserver {
 public:
  explicit AlertLinesWriter(const std::filesystem::path& path,
                            OutputFile::Mode mode = OutputFile::Mode::replace)
      : out_(path, mode) {}
  OutputFile& output() { return out_; }
  void on_zone_event(const fusion::ZoneEvent& event) override;

 private:
  OutputFile out_;
  char buffer_[512];
};

}  // namespace dronetrack::apps
