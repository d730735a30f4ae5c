#include "fusion/track_classifier.hpp"

#include <algorithm>
#include <cmath>

namespace dronetrack::fusion {

const char* to_string(TrackClass track_class) {
  switch (track_class) {
    case TrackClass::unknown:
      return "unknown";
    case TrackClass::drone:
      return "drone";
    case TrackClass::ground:
      return "ground";
    case TrackClass::aircraft:
      return "aircraft";
  }
  return "unknown";
}

std::optional<TrackClass> track_class_from_string(const std::string& name) {
  for (TrackClass c :
       {TrackClass::unknown, TrackClass::drone, TrackClass::ground, TrackClass::aircraft})
    if (name == to_string(c)) return c;
  return std::nullopt;
}

TrackClassifier::TrackClassifier(const ClassifierSettings& settings, double ground_altitude_m)
    : settings_(settings), ground_altitude_m_(ground_altitude_m) {}

void TrackClassifier::add_acoustic(TrackEvidence& evidence, const doa::AcousticFeatures& features,
                                   double time_s) const {
  if (!features.valid) return;
  const double elapsed_s = std::max(0.0, time_s - evidence.acoustic_time_s);
  const double keep = std::exp(-elapsed_s / settings_.acoustic_memory_s);
  evidence.drone_votes *= keep;
  evidence.all_votes *= keep;
  evidence.acoustic_time_s = std::max(evidence.acoustic_time_s, time_s);
  const bool rotor_comb = features.fundamental_hz >= settings_.drone_min_fundamental_hz &&
                          features.fundamental_hz <= settings_.drone_max_fundamental_hz &&
                          features.comb_persistence >= settings_.drone_min_comb_persistence;
  evidence.all_votes += 1.0;
  if (rotor_comb) evidence.drone_votes += 1.0;
}

void TrackClassifier::add_kinematics(TrackEvidence& evidence, const Eigen::Vector3d& position_m,
                                     const Eigen::Vector3d& velocity_mps, double altitude_std_m,
                                     double time_s) const {
  const double altitude_m = position_m.z() - ground_altitude_m_;
  const double speed_mps = velocity_mps.norm();
  if (!std::isfinite(altitude_m) || !std::isfinite(speed_mps)) return;
  if (!evidence.kinematics_started) {
    evidence.altitude_m = altitude_m;
    evidence.speed_mps = speed_mps;
    evidence.altitude_std_m = altitude_std_m;
    evidence.kinematic_time_s = time_s;
    evidence.first_time_s = time_s;
    evidence.kinematics_started = true;
    return;
  }
  const double elapsed_s = std::max(0.0, time_s - evidence.kinematic_time_s);
  const double weight = 1.0 - std::exp(-elapsed_s / settings_.kinematic_memory_s);
  evidence.altitude_m += weight * (altitude_m - evidence.altitude_m);
  evidence.speed_mps += weight * (speed_mps - evidence.speed_mps);
  evidence.altitude_std_m = altitude_std_m;
  evidence.max_speed_mps = std::max(evidence.max_speed_mps, evidence.speed_mps);
  evidence.static_s =
      evidence.speed_mps <= settings_.static_max_speed_mps ? evidence.static_s + elapsed_s : 0.0;
  evidence.kinematic_time_s = time_s;
}

// Order matters: kinematics that no small drone shows veto the acoustics (a light aircraft's
// propeller is a comb too); a track held at ground level is a ground source unless it sounds
// like a drone (a drone landing or flying low keeps its class); then the rotor comb decides.
void TrackClassifier::classify(TrackEvidence& evidence, bool doas_explained_elsewhere) const {
  const ClassifierSettings& s = settings_;
  const double share = evidence.drone_share();
  const bool heard_enough = evidence.all_votes >= s.min_acoustic_votes;
  const bool was_drone = evidence.track_class == TrackClass::drone;
  const bool sounds_like_drone =
      heard_enough && share >= (was_drone ? s.drone_leave_share : s.drone_enter_share);
  if (!evidence.kinematics_started) return;
  // A new track without enough votes yet waits (unknown) rather than flip from ground to drone
  // as its first DOAs arrive; without acoustic features at all it is decided on kinematics.
  if (!heard_enough && evidence.kinematic_time_s - evidence.first_time_s < s.undecided_s) {
    evidence.track_class = TrackClass::unknown;
    evidence.confidence = 0.0;
    return;
  }
  const double altitude_margin = evidence.altitude_m / s.aircraft_min_altitude_m;
  const double speed_margin = evidence.speed_mps / s.aircraft_min_speed_mps;
  const bool altitude_known = evidence.altitude_std_m <= 0.25 * std::max(evidence.altitude_m, 1.0);
  // An aircraft stays one while its altitude could still be an aircraft's: a smoothed altitude
  // sinking a few metres under the threshold within its std (the aircraft's ray from one array,
  // range open: mixed site draw 23, 162 +- 13 m -> 148 +- 18 m) is no drone, however rotor-like
  // its propeller's comb.
  const bool still_aircraft =
      evidence.track_class == TrackClass::aircraft &&
      evidence.altitude_m + evidence.altitude_std_m >= s.aircraft_min_altitude_m;
  if ((altitude_margin >= 1.0 && altitude_known) || speed_margin >= 1.0 || still_aircraft) {
    evidence.track_class = TrackClass::aircraft;
    evidence.confidence =
        std::clamp(0.5 + 0.5 * (std::max(altitude_margin, speed_margin) - 1.0) / 0.5, 0.5, 1.0);
    return;
  }
  const bool low = evidence.altitude_m <= s.ground_max_altitude_m &&
                   evidence.altitude_std_m <= s.ground_max_altitude_std_m;
  const bool parked =
      evidence.static_s >= s.static_long_s && evidence.altitude_m <= s.static_ground_max_altitude_m;
  // At ground level a rotor-like comb is not enough: a generator's or an engine's harmonics can
  // sit in the rotor range, and a drone's own sound reaches the ground-level points where its
  // rays and its echo's cross (the ghost near the ground). Low and still: ground once it has
  // stood still ground_static_s (a drone standing on the ground is no threat either); low with a
  // rotor's comb: unknown, shown to the operator but not alerted on by default.
  if (((low || parked) && !sounds_like_drone) || (low && evidence.static_s >= s.ground_static_s)) {
    evidence.track_class = TrackClass::ground;
    evidence.confidence = heard_enough ? std::clamp(1.0 - share, 0.5, 1.0) : 0.5;
    return;
  }
  // Its altitude estimate at ground level but too uncertain to say ground (a new track fixed by
  // far arrays: a passing car's first ticks at 1.3 +- 2.7 m on the mixed site): a comb there is
  // no more a drone's than at a known ground level. Unknown until the altitude is known.
  if (low || evidence.altitude_m <= s.ground_max_altitude_m) {
    evidence.track_class = TrackClass::unknown;
    evidence.confidence = 0.5;
    return;
  }
  // A comb makes a new drone only above ground level by more than the altitude's own std: a
  // track fixed by far arrays at 3.5 +- 3.3 m (the passing car's first ticks, mixed site draw
  // 26) is no drone on its comb while it could be on the ground. No such bound under the
  // aircraft's altitude: a far drone's one-array track, range open, is at 125 +- 72 m
  // (far_approach scenes) and a drone all the same. A drone keeps its class while its altitude
  // grows uncertain (coasting, far).
  const bool above_ground = evidence.altitude_m - evidence.altitude_std_m > s.ground_max_altitude_m;
  if (sounds_like_drone && (was_drone || (above_ground && !doas_explained_elsewhere))) {
    evidence.track_class = TrackClass::drone;
    evidence.confidence = std::clamp(share, 0.5, 1.0);
    return;
  }
  evidence.track_class = TrackClass::unknown;
  evidence.confidence = heard_enough ? std::clamp(1.0 - share, 0.0, 1.0) : 0.0;
}

}  // namespace dronetrack::fusion
