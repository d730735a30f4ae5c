#include "config/fusion_bounds.hpp"

#include <stdexcept>
#include <utility>

#include "config/config_reader.hpp"

namespace dronetrack::config {
namespace {

// One object's keys against their bounds, worded as ObjectReader words a bad value, so a value
// from the JSON and one a program set read alike.
class KeyBounds {
 public:
  KeyBounds(Diagnostics& diagnostics, std::string path)
      : diagnostics_(diagnostics), path_(std::move(path)) {}
  KeyBounds nested(const std::string& key) const { return {diagnostics_, path_of(key)}; }
  std::string path_of(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }
  bool number(const std::string& key, double value, double min, double max) {
    if (value >= min && value <= max) return true;  // NaN fails too
    diagnostics_.error(path_of(key), "must be in [" + format_number(min) + ", " +
                                         format_number(max) + "], got " + format_number(value));
    return false;
  }
  bool integer(const std::string& key, int value, int min, int max) {
    if (value >= min && value <= max) return true;
    diagnostics_.error(path_of(key), "must be in [" + std::to_string(min) + ", " +
                                         std::to_string(max) + "], got " + std::to_string(value));
    return false;
  }
  // Levels each in (0, max], at most `max_levels` of them.
  void levels(const std::string& key, const std::vector<double>& values, std::size_t max_levels,
              double max, const std::string& max_text) {
    if (values.size() > max_levels) {
      diagnostics_.error(path_of(key), "at most " + std::to_string(max_levels) + " levels");
      return;
    }
    for (std::size_t i = 0; i < values.size(); ++i) {
      if (!(values[i] > 0.0 && values[i] <= max)) {
        diagnostics_.error(path_of(key) + "[" + std::to_string(i) + "]",
                           "must be in (0, " + max_text + "]");
        return;
      }
    }
  }
  void rule(bool ok, const std::string& key, const std::string& what) {
    if (!ok) diagnostics_.error(path_of(key), what);
  }

 private:
  Diagnostics& diagnostics_;
  std::string path_;
};

void check_one_array(const fusion::OneArrayParams& one, KeyBounds fusion_keys) {
  if (one.source_plane_z_m)
    fusion_keys.number("source_plane_z_m", *one.source_plane_z_m, -1e4, 1e4);
  fusion_keys.number("source_plane_std_m", one.source_plane_std_m, 1e-4, 100.0);
  // Keys, units and defaults: docs/fusion.md ("One array alone").
  KeyBounds keys = fusion_keys.nested("single_array");
  keys.number("hypothesis_spacing_m", one.hypothesis_spacing_m, 0.1, 1e4);
  keys.number("hypothesis_range_ratio", one.hypothesis_range_ratio, 1.0, 4.0);
  keys.integer("hypotheses_per_side", one.hypotheses_per_side, 1, 64);
  keys.number("max_range_m", one.max_range_m, 1.0, 1e5);
  keys.number("prune_gamma", one.prune_gamma, 1e-6, 0.999);
  keys.number("merge_d2", one.merge_d2, 0.0, 100.0);
  keys.number("range_init_m", one.range_init_m, 0.1, 1e5);
  keys.number("range_init_std_m", one.range_init_std_m, 0.01, 1e5);
  keys.number("bearing_init_std_deg", one.bearing_init_std_deg, 0.01, 90.0);
  keys.number("jerk_std_mps3", one.jerk_std_mps3, 1e-6, 1e4);
  // A static source's prior (docs/fusion.md "Static sources": 0.01 m/s, 1e-4 m/s^2, 1e-5 m/s^3)
  // must fit: the lower bounds are those of the jerk.
  keys.number("velocity_std_mps", one.velocity_std_mps, 1e-6, 1000.0);
  keys.number("acceleration_std_mps2", one.acceleration_std_mps2, 1e-6, 1000.0);
  keys.integer("particle_count", one.particle_count, 10, 1000000);
}

void check_mirror_check(const fusion::MirrorCheckSettings& m, KeyBounds keys) {
  // Keys, units and defaults: docs/calibration.md ("Swaps the node cannot see").
  const bool gate = keys.number("gate_deg", m.gate_deg, 0.1, 45.0);
  if (keys.number("min_separation_deg", m.min_separation_deg, 1.0, 180.0) && gate)
    keys.rule(m.min_separation_deg > m.gate_deg, "min_separation_deg", "must exceed gate_deg");
  keys.number("evidence_ratio", m.evidence_ratio, 1.5, 1e4);
  keys.number("floor_deg", m.floor_deg, 0.01, 45.0);
  const bool min_sectors = keys.integer("min_sectors", m.min_sectors, 1, 1024);
  keys.number("min_sector_doas", m.min_sector_doas, 1.0, 1e6);
  if (keys.integer("sectors", m.sectors, 1, 1024) && min_sectors)
    keys.rule(m.min_sectors <= m.sectors, "min_sectors", "must not exceed sectors");
  keys.number("window_s", m.window_s, 1.0, 86400.0);
  keys.integer("judge_doas", m.judge_doas, 1, 100000);
  keys.number("symmetry_tolerance", m.symmetry_tolerance, 0.0, 0.2);
  keys.integer("min_other_arrays", m.min_other_arrays, 1, 63);
  keys.number("max_track_angle_deg", m.max_track_angle_deg, 0.01, 45.0);
  keys.number("rewarn_s", m.rewarn_s, 0.0, 86400.0);
}

void check_classifier(const fusion::ClassifierSettings& c, KeyBounds keys) {
  // Keys, units and defaults: docs/classification.md.
  const bool min_hz =
      keys.number("drone_min_fundamental_hz", c.drone_min_fundamental_hz, 1.0, 5000.0);
  if (keys.number("drone_max_fundamental_hz", c.drone_max_fundamental_hz, 1.0, 5000.0) && min_hz)
    keys.rule(c.drone_max_fundamental_hz > c.drone_min_fundamental_hz, "drone_max_fundamental_hz",
              "must exceed drone_min_fundamental_hz");
  keys.number("drone_min_comb_persistence", c.drone_min_comb_persistence, 0.0, 1.0);
  keys.number("acoustic_memory_s", c.acoustic_memory_s, 0.1, 600.0);
  keys.number("min_acoustic_votes", c.min_acoustic_votes, 0.0, 1000.0);
  keys.number("undecided_s", c.undecided_s, 0.0, 600.0);
  const bool enter = keys.number("drone_enter_share", c.drone_enter_share, 0.0, 1.0);
  if (keys.number("drone_leave_share", c.drone_leave_share, 0.0, 1.0) && enter)
    keys.rule(c.drone_leave_share <= c.drone_enter_share, "drone_leave_share",
              "must not exceed drone_enter_share");
  keys.number("kinematic_memory_s", c.kinematic_memory_s, 0.1, 600.0);
  keys.number("ground_max_altitude_m", c.ground_max_altitude_m, 0.0, 1000.0);
  keys.number("ground_max_altitude_std_m", c.ground_max_altitude_std_m, 0.0, 1000.0);
  keys.number("static_max_speed_mps", c.static_max_speed_mps, 0.0, 100.0);
  keys.number("static_long_s", c.static_long_s, 0.0, 86400.0);
  keys.number("static_ground_max_altitude_m", c.static_ground_max_altitude_m, 0.0, 1000.0);
  keys.number("ground_static_s", c.ground_static_s, 0.0, 86400.0);
  keys.number("aircraft_min_altitude_m", c.aircraft_min_altitude_m, 1.0, 1e5);
  keys.number("aircraft_min_speed_mps", c.aircraft_min_speed_mps, 1.0, 1000.0);
}

}  // namespace

void check_fusion_params(const fusion::FusionParams& p, const std::string& path,
                         Diagnostics& diagnostics) {
  KeyBounds keys(diagnostics, path);
  check_one_array(p.single_array, keys);
  keys.number("jerk_noise_std_mps3", p.jerk_noise_std_mps3, 1e-6, 1e4);
  keys.number("output_rate_hz", p.output_rate_hz, 0.1, 1000.0);
  keys.number("reorder_window_s", p.reorder_window_s, 0.0, 10.0);
  keys.number("gate_probability", p.gate_probability, 0.5, 0.999999);
  keys.number("student_t_dof", p.student_t_dof, 1.0, 100.0);
  keys.number("outlier_probability", p.outlier_probability, 0.0, 0.9);
  // A window under 50 DOAs cannot tell e = 0 from e = 0.1 (docs/fusion.md "Estimating e").
  keys.integer("outlier_window_doas", p.outlier_window_doas, 50, 100000);
  keys.number("outlier_prior_doas", p.outlier_prior_doas, 0.0, 100000.0);
  const bool hits = keys.integer("confirm_hits", p.confirm_hits, 1, 1000);
  if (keys.integer("confirm_window", p.confirm_window, 1, 32) && hits)
    keys.rule(p.confirm_hits <= p.confirm_window, "confirm_hits", "must not exceed confirm_window");
  const bool timeout = keys.number("coast_timeout_s", p.coast_timeout_s, 0.1, 600.0);
  keys.number("ukf_alpha", p.ukf_alpha, 1e-4, 10.0);
  keys.number("ukf_beta", p.ukf_beta, 0.0, 10.0);
  // Above -9: alpha^2 (9 + kappa) > 0, the sigma points' spread.
  keys.number("ukf_kappa", p.ukf_kappa, -8.9, 100.0);
  keys.integer("particle_count", p.particle_count, 10, 1000000);
  keys.number("doa_noise_floor_deg", p.doa_noise_floor_deg, 0.0, 45.0);
  if (keys.number("coast_after_s", p.coast_after_s, 0.01, 600.0) && timeout)
    keys.rule(p.coast_after_s <= p.coast_timeout_s, "coast_after_s",
              "must not exceed coast_timeout_s");
  keys.number("tentative_timeout_s", p.tentative_timeout_s, 0.01, 600.0);
  keys.number("init_pair_window_s", p.init_pair_window_s, 0.001, 10.0);
  keys.number("init_max_range_m", p.init_max_range_m, 1.0, 1e5);
  keys.number("init_max_speed_mps", p.init_max_speed_mps, 0.0, 1000.0);
  keys.number("init_velocity_std_mps", p.init_velocity_std_mps, 0.01, 1000.0);
  keys.number("init_acceleration_std_mps2", p.init_acceleration_std_mps2, 0.01, 1000.0);
  keys.integer("max_tracks", p.max_tracks, 1, 1000);
  keys.integer("confirm_min_arrays", p.confirm_min_arrays, 1, 64);
  keys.number("max_position_std_m", p.max_position_std_m, 0.1, 1e5);
  keys.levels("imm_jerk_std_mps3", p.imm_jerk_std_mps3, 8, 1e4, "10000");
  keys.number("imm_sojourn_s", p.imm_sojourn_s, 0.01, 1e4);
  keys.levels("imm_turn_rate_std_radps2", p.imm_turn_rate_std_radps2, 4, 1e3, "1000");
  keys.number("imm_turn_jerk_std_mps3", p.imm_turn_jerk_std_mps3, 1e-6, 1e4);
  keys.number("doa_error_correlation_s", p.doa_error_correlation_s, 0.0, 60.0);
  keys.number("ground_altitude_m", p.ground_altitude_m, -1e4, 1e4);
  check_mirror_check(p.mirror_check, keys.nested("mirror_check"));
  check_classifier(p.classifier, keys.nested("classifier"));
}

std::vector<std::string> fusion_params_problems(const fusion::FusionParams& params) {
  Diagnostics diagnostics;
  check_fusion_params(params, "fusion", diagnostics);
  return std::move(diagnostics.errors);
}

void validate(const fusion::FusionParams& params) {
  const std::vector<std::string> problems = fusion_params_problems(params);
  if (problems.empty()) return;
  std::string text;
  for (const std::string& problem : problems) text += (text.empty() ? "" : "\n") + problem;
  throw std::invalid_argument(text);
}

}  // namespace dronetrack::config
