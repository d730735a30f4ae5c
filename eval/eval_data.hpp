#pragma once
// What the evaluation reads (simulator truth, SPEC 3.2b; DOA and track JSON lines, SPEC 3.2)
// and what it reports (SPEC 4.7). Plain structs: the metrics are computed by pure functions.
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "doa/doa_measurement.hpp"

namespace dronetrack::eval {

struct TruthSource {
  std::string id;
  std::vector<double> time_s;  // increasing, common to every column
  std::vector<Eigen::Vector3d> position_m;
  // Per array id: unit direction (site frame) toward where the source was when the sound
  // arriving at time_s[i] left it.
  std::map<std::string, std::vector<Eigen::Vector3d>> direction_by_array;

  bool alive_at(double t) const {
    // Within rounding: an eval tick k * step may land a few ulps past the last truth sample.
    constexpr double kSlack_s = 1e-9;
    return !time_s.empty() && t >= time_s.front() - kSlack_s && t <= time_s.back() + kSlack_s;
  }
  Eigen::Vector3d position_at(double t) const;  // linear interpolation, clamped
  // Interpolated and normalised; nullopt if this array has no truth directions.
  std::optional<Eigen::Vector3d> direction_at(const std::string& array, double t) const;
};

struct Truth {
  std::vector<TruthSource> sources;  // drones only (interferers are not targets)
  // The other sources (truth "interferers"), each with its class ("class", else from "kind":
  // "ground" unless given): what a track that follows no drone is following (issue 14).
  std::vector<TruthSource> others;
  std::vector<std::string> other_classes;
  std::map<std::string, Eigen::Vector3d> array_centres_m;  // optional "arrays" key
  std::optional<double> recording_end_s;                   // earliest recording end, if given
};

struct DoaRecord {
  double time_s = 0.0;
  std::string array;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
  // Optional in SPEC 3.2's minimal line; `replay --doa-in` feeds them to the fusion.
  int source_index = 0;
  double quality = 0.0;
  double snr_db = 0.0;
  std::string ambiguity = "none";               // none | mirror_up_down | cone
  std::optional<Eigen::Vector2d> azel_std_deg;  // absent: the reader of the file decides
  double azel_correlation = 0.0;                // of the azimuth and elevation errors
  doa::AcousticFeatures acoustic;               // "acoustic" object (valid when present)
  // Issue 15, each present only when so measured: a moving array's pose at the frame's time
  // ("pose"), what a two-mic array measured ("cone"), a planar array's plane ("mirror_normal").
  struct Pose {
    Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d attitude_deg = Eigen::Vector3d::Zero();  // yaw, pitch, roll
  };
  struct Cone {
    Eigen::Vector3d axis = Eigen::Vector3d::UnitX();
    double angle_deg = 0.0;
    double angle_std_deg = 0.0;
    std::vector<double> peaks_deg;  // the GCC's strongest peaks as cone angles, strongest first
    std::vector<double> peak_weights;
  };
  std::optional<Pose> pose;
  std::optional<Cone> cone;
  std::optional<Eigen::Vector3d> mirror_normal;
  int line = 0;  // in its file, for messages
};

struct TrackRecord {
  double time_s = 0.0;
  int id = 0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  std::string status;                   // tentative | confirmed | coasting
  std::string track_class = "unknown";  // "class": drone | ground | aircraft | unknown
  // A track resting on one array (issue 15: "one_array": true) and its stated 1-sigma extent
  // ("position_std_m"; absent: unknown, 0).
  bool one_array = false;
  Eigen::Vector3d position_std_m = Eigen::Vector3d::Zero();
};

// An alert line (`replay --alerts-out`).
struct AlertRecord {
  double time_s = 0.0;
  std::string zone;
  int track_id = 0;
  std::string event;  // entered | left | class_changed
};

struct EvalOptions {
  double association_gate_m = 10.0;  // a track farther than this from every truth is false
  double coverage_gate_m = 5.0;      // covered: an associated track within this distance
  double tick_s = 0.0;               // evaluation step; 0: the tracks' own output interval
  double skip_s = 0.0;               // ignore the first seconds (sound still in flight)
  bool include_tentative = false;    // tentative tracks count as tracks
  // A source has converged once every later error of its associated tracks is within this
  // (static and slow sources, issue 15: the papers' "time to converge").
  double converge_gate_m = 3.0;
  // A one-array track (issue 15) knows its bearing, not its range: it follows a source when, seen
  // from some array, it lies within this angle of the source AND the source lies within its own
  // stated 99 % extent; then it is associated and covers the source whatever its metric error.
  double one_array_bearing_gate_deg = 3.0;
};

struct PositionMetrics {
  int samples = 0;
  double rmse_3d_m = 0.0;
  double median_error_m = 0.0;
  double p90_error_m = 0.0;
  double max_error_m = 0.0;
  double rmse_horizontal_m = 0.0;
  double rmse_vertical_m = 0.0;
  // Seed 002 eq. 35, positions relative to the array centroid: the mean over samples of
  // |truth - estimate| / |truth| (total), and of the same per axis, in percent.
  double pfe_total_percent = 0.0;
  Eigen::Vector3d pfe_axis_percent = Eigen::Vector3d::Zero();
};

// One tick's 3-D error of the track assigned to a source (for plots: error over time).
struct ErrorSample {
  double time_s = 0.0;
  int track_id = 0;
  double error_m = 0.0;
};

struct SourceMetrics {
  std::string id;
  std::vector<ErrorSample> errors;  // every tick a counted track was assigned to it, in order
  // Drone or not (issue 14), over the ticks a counted track follows this drone:
  double tracked_time_s = 0.0;
  double drone_class_time_s = 0.0;   // of which the track said "drone"
  double drone_class_share = 0.0;    // drone_class_time_s / tracked_time_s
  double first_tracked_s = -1.0;     // first tick a counted track followed it
  double classified_after_s = -1.0;  // then until its track first said "drone" (-1: never)
  PositionMetrics position;
  double truth_time_s = 0.0;
  double covered_time_s = 0.0;
  double coverage = 0.0;  // covered / truth time
  int id_switches = 0;
  std::vector<int> track_ids;  // every track id associated with it
  // Localisation of static and slow sources (issue 15): the error at the last tick a track
  // followed it, and the time from its first tick in the window until its errors stayed within
  // EvalOptions::converge_gate_m for good (-1: never tracked / never converged).
  double final_error_m = -1.0;
  double converged_after_s = -1.0;
  double travelled_m = 0.0;       // path length of the truth in the window (0: a static source)
  double one_array_time_s = 0.0;  // of tracked_time_s, followed by a one-array track
};

struct DoaArrayMetrics {
  std::string array;
  std::vector<double> time_s;     // each matched DOA's time ...
  std::vector<double> error_deg;  // ... and its error (for plots: DOA error over time)
  int count = 0;
  double median_error_deg = 0.0;
  double p90_error_deg = 0.0;
  double mean_error_deg = 0.0;
};

// A source that is not a drone (generator, car, aircraft, bird): how long a counted track
// followed it, and how long that track said "drone".
struct OtherSourceMetrics {
  std::string id;
  std::string source_class;
  double tracked_time_s = 0.0;
  double as_drone_time_s = 0.0;
};

struct EvalReport {
  EvalOptions options;
  double tick_s = 0.0;
  double start_s = 0.0;
  double end_s = 0.0;
  Eigen::Vector3d array_centroid_m = Eigen::Vector3d::Zero();
  PositionMetrics position;  // all sources together
  std::vector<SourceMetrics> sources;
  double coverage = 0.0;  // all sources' covered time / truth time
  int id_switches = 0;
  int tracks_seen = 0;                // distinct ids counted as tracks
  double track_time_s = 0.0;          // sum over counted tracks of their time
  double false_track_time_s = 0.0;    // of which associated to no truth
  double false_track_fraction = 0.0;  // false / track time
  // Of the false-track time, that near no other source of the truth either (a ghost, a
  // reflection): the rest follows a real non-drone source (an aircraft tracked and classed as
  // one is false-track time, not a ghost).
  double ghost_track_time_s = 0.0;
  double ghost_track_fraction = 0.0;  // ghost / track time
  std::vector<OtherSourceMetrics> others;
  // Track time of counted tracks that follow no drone (another source or nothing) while they
  // say "drone", and that over the run (end - start): issue 14's "<= 1 % of the run".
  double non_drone_as_drone_time_s = 0.0;
  double non_drone_as_drone_fraction = 0.0;
  // With alerts: zone entries by tracks following a drone, and by any other track.
  int alerts_read = -1;  // -1: no alerts given
  int drone_zone_entries = 0;
  int non_drone_zone_entries = 0;
  std::vector<DoaArrayMetrics> doa;  // empty without DOAs
  int doa_unmatched = 0;             // DOAs of arrays or times without truth
};

}  // namespace dronetrack::eval
