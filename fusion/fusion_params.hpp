#pragma once
// Fusion parameters. Parsed and validated in config/ (parse_fusion_params.cpp).
#include <string>
#include <vector>

#include <Eigen/Core>

namespace dronetrack::fusion {

enum class FilterKind { ukf, ukf_seed002, ekf, particle };

struct FusionParams {
  FilterKind filter = FilterKind::ukf;
  double jerk_noise_std_mps3 = 3.0;  // sqrt(q) of the constant-jerk model (SPEC 4.5)
  double output_rate_hz = 10.0;      // track reports per second
  double reorder_window_s = 0.3;     // DOAs are fed oldest first after this delay
  double gate_probability = 0.999;   // chi-square gate on the DOA innovation
  int confirm_hits = 5;              // M of N: M
  int confirm_window = 8;            //         N
  double coast_timeout_s = 3.0;      // a track unheard this long is deleted
};

// A zone alerts when a track enters or leaves it: a polygon in the x-y plane (site frame)
// with an altitude band.
struct Zone {
  std::string name;
  std::vector<Eigen::Vector2d> polygon_m;
  double altitude_min_m = -1e9;
  double altitude_max_m = 1e9;
};

}  // namespace dronetrack::fusion
