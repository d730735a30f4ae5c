#pragma once
// Fusion parameters. Parsed and validated in config/ (parse_fusion_params.cpp).
#include <string>
#include <vector>

#include <Eigen/Core>

namespace dronetrack::fusion {

enum class FilterKind { ukf, ukf_seed002, ekf, particle };
// How a new track's first position is found (SPEC 4.4).
enum class TriangulationMethod { least_squares_3d, seed_xy_projection };

struct FusionParams {
  FilterKind filter = FilterKind::ukf;
  double jerk_noise_std_mps3 = 5.0;  // sqrt(q) of the constant-jerk model (SPEC 4.5)
  double output_rate_hz = 10.0;      // track reports per second
  double reorder_window_s = 0.3;     // DOAs are fed oldest first after this delay
  double gate_probability = 0.999;   // chi-square gate on the DOA innovation
  int confirm_hits = 5;              // M of N: M
  int confirm_window = 8;            //         N
  double coast_timeout_s = 3.0;      // a track unheard this long is deleted

  // Scaled unscented transform (filter = ukf). alpha = 1, kappa = 0 keeps every weight >= 0.
  double ukf_alpha = 1.0;
  double ukf_beta = 2.0;
  double ukf_kappa = 0.0;
  int particle_count = 1000;  // filter = particle
  // Point h(x) at the emission time (sound takes r / c to arrive). Off only for comparison.
  bool model_propagation_delay = true;
  TriangulationMethod triangulation = TriangulationMethod::least_squares_3d;
  // Added in quadrature to each DOA's own angular std: model error (array pose, wind, refraction).
  double doa_noise_floor_deg = 0.3;
  double coast_after_s = 0.5;        // a confirmed track unheard this long reports "coasting"
  double tentative_timeout_s = 1.5;  // a tentative track unheard this long is deleted
  // Initiation: DOAs of different arrays this close in time are paired and triangulated.
  double init_pair_window_s = 0.3;
  double init_max_range_m = 2000.0;  // candidate points farther from every array are rejected
  double init_max_speed_mps = 25.0;  // bounds the motion between paired DOAs (widens their gate)
  double init_velocity_std_mps = 10.0;
  double init_acceleration_std_mps2 = 3.0;
  int max_tracks = 32;
  // Ghost rejection by continuity: a tentative track is confirmed only once this many distinct
  // arrays have updated it (clamped to the number of arrays). A crossing of two drones' rays is
  // consistent with the two arrays that made it, rarely with a third.
  // Two arrays that each updated it confirm_hits times also suffice (continuity: a ghost does not
  // keep agreeing with both while the drones move), for a drone the other arrays cannot hear.
  int confirm_min_arrays = 3;
  // A track whose position std (largest axis) grows beyond this is lost, not tracked: deleted.
  double max_position_std_m = 50.0;
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
