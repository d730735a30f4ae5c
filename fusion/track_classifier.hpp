#pragma once
// Drone or not (issue 14): each track's class from the acoustic evidence its DOAs carry (the
// nodes' per-source comb features, doa/acoustic_features.hpp) and its own kinematics (altitude
// above the local ground, speed, how long it has stood still). Rules and every threshold:
// docs/classification.md. Plain functions on a per-track evidence struct; the engine owns one
// TrackEvidence per track and asks classify() after every update.
#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "doa/doa_measurement.hpp"

namespace dronetrack::fusion {

enum class TrackClass : std::uint8_t { unknown = 0, drone = 1, ground = 2, aircraft = 3 };
const char* to_string(TrackClass track_class);
std::optional<TrackClass> track_class_from_string(const std::string& name);

struct ClassifierSettings {
  // A DOA speaks for a drone when its source shows a rotor comb: spacing in this range, found
  // in at least this share of the node's recent analyses of that source.
  double drone_min_fundamental_hz = 80.0;
  double drone_max_fundamental_hz = 400.0;
  double drone_min_comb_persistence = 0.3;
  double acoustic_memory_s = 4.0;   // the DOAs' votes fade with this time constant
  double min_acoustic_votes = 4.0;  // effective DOAs in memory before the acoustics decide
  double undecided_s = 2.0;         // a track with fewer votes stays unknown this long
  double drone_enter_share = 0.5;   // share of drone votes to become a drone
  double drone_leave_share = 0.2;   // and to stop being one (hysteresis)
  double kinematic_memory_s = 2.0;  // smoothing of altitude and speed
  // Ground: a track that stays this low above the local ground (altitude std small enough to
  // say so), or stands still for long this low, is a ground source (generator, vehicle, pump).
  double ground_max_altitude_m = 3.0;
  double ground_max_altitude_std_m = 2.0;
  double static_max_speed_mps = 1.0;
  double static_long_s = 30.0;
  double static_ground_max_altitude_m = 8.0;
  // A track this low that has stood still this long is ground whatever it sounds like.
  double ground_static_s = 5.0;
  // Aircraft: higher or faster than a small drone flies (120 m is the usual drone ceiling).
  double aircraft_min_altitude_m = 150.0;
  double aircraft_min_speed_mps = 35.0;
};

// What one track has shown so far. Value type, owned by the engine's track.
struct TrackEvidence {
  double drone_votes = 0.0;  // exponentially weighted count of DOAs with a drone comb
  double all_votes = 0.0;    // of DOAs with acoustic features
  double acoustic_time_s = -1e300;
  double altitude_m = 0.0;  // smoothed, above the local ground
  double altitude_std_m = 1e9;
  double speed_mps = 0.0;  // smoothed
  double max_speed_mps = 0.0;
  double static_s = 0.0;  // how long it has stood still
  double kinematic_time_s = -1e300;
  double first_time_s = 0.0;  // of its first kinematics
  bool kinematics_started = false;
  TrackClass track_class = TrackClass::unknown;
  double confidence = 0.0;
  double drone_share() const { return all_votes > 0.0 ? drone_votes / all_votes : 0.0; }
};

class TrackClassifier {
 public:
  // `settings` as config::check_fusion_params checks them (their bounds live there alone).
  TrackClassifier(const ClassifierSettings& settings, double ground_altitude_m);

  // One DOA the track took (features invalid: no vote).
  void add_acoustic(TrackEvidence& evidence, const doa::AcousticFeatures& features,
                    double time_s) const;
  // The track's state at time_s.
  void add_kinematics(TrackEvidence& evidence, const Eigen::Vector3d& position_m,
                      const Eigen::Vector3d& velocity_mps, double altitude_std_m,
                      double time_s) const;
  // Updates evidence.track_class and .confidence from what it holds. doas_explained_elsewhere:
  // from every array that hears it the track lies along a better-fixed confirmed track's ray
  // (TrackConfirmation::along_sharper_tracks), so its comb is that track's and does not make it
  // a drone.
  void classify(TrackEvidence& evidence, bool doas_explained_elsewhere = false) const;

  const ClassifierSettings& settings() const { return settings_; }

 private:
  ClassifierSettings settings_;
  double ground_altitude_m_;
};

}  // namespace dronetrack::fusion
