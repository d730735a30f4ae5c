#pragma once
// A calibration flight synthesised from physics: true arrays (nominal + injected errors), a
// source on an analytic path, each frame's pair delays from the exact emission time at the
// array's centre plus the channels' delays, Gaussian TDOA noise, and a GPS log with Gaussian
// fixes. Independent of calib/'s own model code (its own emission-time solve on the analytic
// path, its own rotation via Eigen).
#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "calib/site_calibration.hpp"

namespace dronetrack::calib::testing {

inline std::vector<Eigen::Vector3d> tetrahedron_mics(double arm_m) {
  const double s = arm_m;
  return {{0.0, 0.0, s},
          {0.9428 * s, 0.0, -s / 3.0},
          {-0.4714 * s, 0.8165 * s, -s / 3.0},
          {-0.4714 * s, -0.8165 * s, -s / 3.0}};
}

// What is wrong with one array: the calibration's unknowns.
struct InjectedErrors {
  Eigen::Vector3d attitude_deg = Eigen::Vector3d::Zero();  // yaw, pitch, roll
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> mic_offsets_m;  // array frame
  std::vector<double> channel_delay_s;         // [0] = 0
  double clock_offset_s = 0.0;
};

inline InjectedErrors draw_errors(const ArrayNominal& array, const CalibrationPriors& priors,
                                  std::mt19937_64& random) {
  std::normal_distribution<double> normal(0.0, 1.0);
  InjectedErrors errors;
  for (int k = 0; k < 3; ++k) errors.attitude_deg(k) = priors.attitude_std_deg * normal(random);
  for (int k = 0; k < 3; ++k) errors.position_m(k) = priors.array_position_std_m * normal(random);
  for (std::size_t i = 0; i < array.mics_m.size(); ++i) {
    errors.mic_offsets_m.emplace_back(array.mic_position_std_m * normal(random),
                                      array.mic_position_std_m * normal(random),
                                      array.mic_position_std_m * normal(random));
    errors.channel_delay_s.push_back(i == 0 ? 0.0 : priors.channel_delay_std_s * normal(random));
  }
  errors.clock_offset_s = priors.clock_offset_std_s * normal(random);
  return errors;
}

inline Eigen::Matrix3d rotation_deg(double yaw, double pitch, double roll) {
  constexpr double k = std::numbers::pi / 180.0;
  return (Eigen::AngleAxisd(yaw * k, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch * k, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll * k, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

inline std::vector<Eigen::Vector3d> true_mics_site(const ArrayNominal& array,
                                                   const InjectedErrors& errors) {
  const Eigen::Matrix3d r =
      rotation_deg(array.yaw_deg + errors.attitude_deg(0), array.pitch_deg + errors.attitude_deg(1),
                   array.roll_deg + errors.attitude_deg(2));
  std::vector<Eigen::Vector3d> out;
  for (std::size_t i = 0; i < array.mics_m.size(); ++i)
    out.push_back(array.position_m + errors.position_m +
                  r * (array.mics_m[i] + errors.mic_offsets_m[i]));
  return out;
}

struct FlightSettings {
  double duration_s = 40.0;
  double frame_interval_s = 0.1;  // per array
  double gps_interval_s = 0.1;
  double tdoa_std_s = 10e-6;
  double gps_std_m = 0.5;
  double speed_of_sound_mps = 343.0;
};

struct Flight {
  std::vector<TdoaFrame> frames;
  std::vector<ReferenceSample> gps;
};

using Path = std::function<Eigen::Vector3d(double)>;

inline Flight fly(const std::vector<ArrayNominal>& arrays,
                  const std::vector<InjectedErrors>& errors, const Path& path,
                  const FlightSettings& settings, std::mt19937_64& random) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Flight flight;
  const double c = settings.speed_of_sound_mps;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    const std::vector<Eigen::Vector3d> mics = true_mics_site(arrays[a], errors[a]);
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& mic : mics) centre += mic;
    centre /= static_cast<double>(mics.size());
    for (double t_rec = 0.5; t_rec < settings.duration_s; t_rec += settings.frame_interval_s) {
      const double arrival = t_rec - errors[a].clock_offset_s;  // on the true clock
      double emission = arrival;
      for (int k = 0; k < 50; ++k) emission = arrival - (path(emission) - centre).norm() / c;
      if (emission < 0.2) continue;
      const Eigen::Vector3d source = path(emission);
      TdoaFrame frame;
      frame.array = static_cast<int>(a);
      frame.time_s = t_rec;
      for (std::size_t i = 0; i < mics.size(); ++i) {
        for (std::size_t j = i + 1; j < mics.size(); ++j) {
          const double tau = ((source - mics[i]).norm() - (source - mics[j]).norm()) / c +
                             errors[a].channel_delay_s[i] - errors[a].channel_delay_s[j];
          frame.tdoa_s.push_back(tau + settings.tdoa_std_s * normal(random));
        }
      }
      flight.frames.push_back(std::move(frame));
    }
  }
  for (double t = 0.0; t <= settings.duration_s + 1e-9; t += settings.gps_interval_s) {
    const Eigen::Vector3d noise(normal(random), normal(random), normal(random));
    flight.gps.push_back({t, path(t) + settings.gps_std_m * noise});
  }
  return flight;
}

// Two tetrahedral arrays 40 m apart; the source loops twice around them, climbing and sinking.
inline std::vector<ArrayNominal> two_arrays(double mic_position_std_m) {
  ArrayNominal a1;
  a1.id = "A1";
  a1.position_m = {0.0, 0.0, 1.5};
  a1.yaw_deg = 10.0;
  a1.mics_m = tetrahedron_mics(0.5);
  a1.mic_position_std_m = mic_position_std_m;
  ArrayNominal a2 = a1;
  a2.id = "A2";
  a2.position_m = {40.0, 0.0, 1.5};
  a2.yaw_deg = -35.0;
  return {a1, a2};
}

inline Eigen::Vector3d looping_path(double t) {
  const double w = 2.0 * std::numbers::pi / 25.0;
  return {20.0 + 35.0 * std::cos(w * t), 25.0 * std::sin(w * t),
          20.0 + 12.0 * std::sin(2.0 * w * t + 0.5)};
}

}  // namespace dronetrack::calib::testing
