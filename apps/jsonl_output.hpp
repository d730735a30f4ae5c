#pragma once
// JSON-lines outputs of SPEC 3.2 (DOAs, tracks) as fusion observers writing to a file or stdout.
// Formatted with snprintf into a reused buffer: this runs for every DOA of a long replay.
#include <cstdio>
#include <filesystem>
#include <string>

#include "apps/fusion_observer.hpp"

namespace dronetrack::apps {

// One open output: a file, or stdout for "-". Throws a one-line error if it cannot be created.
class OutputFile {
 public:
  explicit OutputFile(const std::filesystem::path& path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  void write_line(const char* text, int length);
  void flush();

 private:
  std::FILE* file_ = nullptr;
  bool owned_ = false;
  std::string path_;
};

// {"t":..,"array":"A1","direction":[..],"azimuth_deg":..,"elevation_deg":..,"quality":..,...}
int format_doa_line(const doa::DoaMeasurement& doa, char* buffer, std::size_t size);
// {"t":..,"id":..,"position_m":[..],"velocity_mps":[..],"acceleration_mps2":[..],
//  "position_std_m":[..],"status":"..","class":"..","class_confidence":..}
int format_track_line(double time_s, const fusion::TrackReport& track, char* buffer,
                      std::size_t size);

class DoaLinesWriter : public FusionObserver {
 public:
  explicit DoaLinesWriter(const std::filesystem::path& path) : out_(path) {}
  void on_doa(const doa::DoaMeasurement& doa) override;

 private:
  OutputFile out_;
  char buffer_[1024];
};

class TrackLinesWriter : public FusionObserver {
 public:
  explicit TrackLinesWriter(const std::filesystem::path& path) : out_(path) {}
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) override;

 private:
  OutputFile out_;
  char buffer_[1024];
};

// {"t":..,"zone":"..","track_id":..,"event":"entered|left|class_changed","class":"..",
//  ["previous_class":"..",] "position_m":[..]}
int format_alert_line(const fusion::ZoneEvent& event, char* buffer, std::size_t size);

class AlertLinesWriter : public FusionObserver {
 public:
  explicit AlertLinesWriter(const std::filesystem::path& path) : out_(path) {}
  void on_zone_event(const fusion::ZoneEvent& event) override;

 private:
  OutputFile out_;
  char buffer_[512];
};

}  // namespace dronetrack::apps
