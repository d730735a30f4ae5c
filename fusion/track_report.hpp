#pragma once
// What the fusion reports about one live track at one time (SPEC 3.2 tracks line).
#include <cstdint>

#include <Eigen/Core>

#include "fusion/track_classifier.hpp"

namespace dronetrack::fusion {

enum class TrackStatus : std::uint8_t { tentative = 0, confirmed = 1, coasting = 2 };
const char* to_string(TrackStatus status);

struct TrackReport {
  int id = 0;
  double time_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d acceleration_mps2 = Eigen::Vector3d::Zero();
  // State order [px py pz vx vy vz ax ay az].
  Eigen::Matrix<double, 9, 9> covariance = Eigen::Matrix<double, 9, 9>::Identity();
  TrackStatus status = TrackStatus::tentative;
  std::uint64_t contributing_arrays = 0;  // bit i: array index i updated this track recently
  double last_update_s = 0.0;
  TrackClass track_class = TrackClass::unknown;  // fusion/track_classifier.hpp
  double class_confidence = 0.0;                 // 0..1
  double confirmed_s = -1.0;  // how long it has been confirmed (< 0: not confirmed)
  // Issue 15: the track rests on one array (started from its DOAs alone; its range comes from
  // hypotheses or the platform's motion, and its covariance says so), and how many hypotheses
  // (Gaussians of a Gaussian sum) it still carries.
  bool one_array = false;
  int hypotheses = 1;
  Eigen::Vector3d position_std_m() const { return covariance.diagonal().head<3>().cwiseSqrt(); }
};

}  // namespace dronetrack::fusion
