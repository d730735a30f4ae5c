#include <string>

#include "config/fusion_bounds.hpp"
#include "config/parse_sections.hpp"

namespace dronetrack::config {

// Reads the keys' types; their bounds are checked on the params read (config/fusion_bounds.cpp),
// the one place a program that fills FusionParams by hand checks them too.
void parse_fusion_params(ObjectReader& section, fusion::FusionParams& params) {
  const auto filter_kind = [](const std::string& name) {
    if (name == "ukf_seed002") return fusion::FilterKind::ukf_seed002;
    if (name == "ekf") return fusion::FilterKind::ekf;
    if (name == "particle") return fusion::FilterKind::particle;
    if (name == "gaussian_sum") return fusion::FilterKind::gaussian_sum;
    if (name == "ekf_range_init") return fusion::FilterKind::ekf_range_init;
    if (name == "particle_multipeak") return fusion::FilterKind::particle_multipeak;
    return fusion::FilterKind::ukf;
  };
  params.filter =
      filter_kind(section.choice("filter", "ukf",
                                 {"ukf", "ukf_seed002", "ekf", "particle", "gaussian_sum",
                                  "ekf_range_init", "particle_multipeak"}));
  // Issue 15: tracks from one array's DOAs alone, and the known source plane.
  params.single_array_start = section.boolean("single_array_start", params.single_array_start);
  params.single_array_filter =
      filter_kind(section.choice("single_array_filter", "gaussian_sum",
                                 {"gaussian_sum", "ekf_range_init", "particle_multipeak"}));
  fusion::OneArrayParams& one = params.single_array;
  if (section.has("source_plane_z_m"))
    one.source_plane_z_m = section.number("source_plane_z_m", 0.0);
  one.source_plane_std_m = section.number("source_plane_std_m", one.source_plane_std_m);
  if (section.has("single_array")) {
    // Keys, units and defaults: docs/fusion.md ("One array alone").
    ObjectReader reader = section.object("single_array");
    one.hypothesis_spacing_m = reader.number("hypothesis_spacing_m", one.hypothesis_spacing_m);
    one.hypothesis_range_ratio =
        reader.number("hypothesis_range_ratio", one.hypothesis_range_ratio);
    one.own_spread_weights = reader.boolean("own_spread_weights", one.own_spread_weights);
    one.hypotheses_per_side = reader.integer("hypotheses_per_side", one.hypotheses_per_side);
    one.max_range_m = reader.number("max_range_m", one.max_range_m);
    one.prune_gamma = reader.number("prune_gamma", one.prune_gamma);
    one.merge_d2 = reader.number("merge_d2", one.merge_d2);
    one.range_init_m = reader.number("range_init_m", one.range_init_m);
    one.range_init_std_m = reader.number("range_init_std_m", one.range_init_std_m);
    one.bearing_init_std_deg = reader.number("bearing_init_std_deg", one.bearing_init_std_deg);
    one.jerk_std_mps3 = reader.number("jerk_std_mps3", one.jerk_std_mps3);
    one.velocity_std_mps = reader.number("velocity_std_mps", one.velocity_std_mps);
    one.acceleration_std_mps2 = reader.number("acceleration_std_mps2", one.acceleration_std_mps2);
    one.particle_count = reader.integer("particle_count", one.particle_count);
  }
  params.jerk_noise_std_mps3 = section.number("jerk_noise_std_mps3", params.jerk_noise_std_mps3);
  params.output_rate_hz = section.number("output_rate_hz", params.output_rate_hz);
  params.reorder_window_s = section.number("reorder_window_s", params.reorder_window_s);
  params.gate_probability = section.number("gate_probability", params.gate_probability);
  const std::string likelihood =
      section.choice("likelihood", "outlier_mixture", {"gaussian", "student_t", "outlier_mixture"});
  params.likelihood = likelihood == "gaussian"    ? fusion::DoaLikelihoodKind::gaussian
                      : likelihood == "student_t" ? fusion::DoaLikelihoodKind::student_t
                                                  : fusion::DoaLikelihoodKind::outlier_mixture;
  params.student_t_dof = section.number("student_t_dof", params.student_t_dof);
  params.outlier_probability = section.number("outlier_probability", params.outlier_probability);
  params.adaptive_outlier_probability =
      section.boolean("adaptive_outlier_probability", params.adaptive_outlier_probability);
  params.outlier_window_doas = section.integer("outlier_window_doas", params.outlier_window_doas);
  params.outlier_prior_doas = section.number("outlier_prior_doas", params.outlier_prior_doas);
  params.confirm_hits = section.integer("confirm_hits", params.confirm_hits);
  params.confirm_window = section.integer("confirm_window", params.confirm_window);
  params.coast_timeout_s = section.number("coast_timeout_s", params.coast_timeout_s);
  params.ukf_alpha = section.number("ukf_alpha", params.ukf_alpha);
  params.ukf_beta = section.number("ukf_beta", params.ukf_beta);
  params.ukf_kappa = section.number("ukf_kappa", params.ukf_kappa);
  params.particle_count = section.integer("particle_count", params.particle_count);
  params.model_propagation_delay =
      section.boolean("model_propagation_delay", params.model_propagation_delay);
  const std::string triangulation = section.choice("triangulation", "least_squares_3d",
                                                   {"least_squares_3d", "seed_xy_projection"});
  params.triangulation = triangulation == "seed_xy_projection"
                             ? fusion::TriangulationMethod::seed_xy_projection
                             : fusion::TriangulationMethod::least_squares_3d;
  params.doa_noise_floor_deg = section.number("doa_noise_floor_deg", params.doa_noise_floor_deg);
  params.coast_after_s = section.number("coast_after_s", params.coast_after_s);
  params.tentative_timeout_s = section.number("tentative_timeout_s", params.tentative_timeout_s);
  params.init_pair_window_s = section.number("init_pair_window_s", params.init_pair_window_s);
  params.init_max_range_m = section.number("init_max_range_m", params.init_max_range_m);
  params.init_max_speed_mps = section.number("init_max_speed_mps", params.init_max_speed_mps);
  params.init_velocity_std_mps =
      section.number("init_velocity_std_mps", params.init_velocity_std_mps);
  params.init_acceleration_std_mps2 =
      section.number("init_acceleration_std_mps2", params.init_acceleration_std_mps2);
  params.max_tracks = section.integer("max_tracks", params.max_tracks);
  params.confirm_min_arrays = section.integer("confirm_min_arrays", params.confirm_min_arrays);
  params.max_position_std_m = section.number("max_position_std_m", params.max_position_std_m);
  if (auto levels = section.numbers("imm_jerk_std_mps3", 0, false))
    params.imm_jerk_std_mps3 = *levels;
  params.imm_sojourn_s = section.number("imm_sojourn_s", params.imm_sojourn_s);
  params.imm_turn_mode = section.boolean("imm_turn_mode", params.imm_turn_mode);
  if (auto levels = section.numbers("imm_turn_rate_std_radps2", 0, false))
    params.imm_turn_rate_std_radps2 = *levels;
  params.imm_turn_jerk_std_mps3 =
      section.number("imm_turn_jerk_std_mps3", params.imm_turn_jerk_std_mps3);
  params.doa_error_correlation_s =
      section.number("doa_error_correlation_s", params.doa_error_correlation_s);
  params.ground_altitude_m = section.number("ground_altitude_m", params.ground_altitude_m);
  if (section.has("mirror_check")) {
    // Keys, units and defaults: docs/calibration.md ("Swaps the node cannot see").
    ObjectReader reader = section.object("mirror_check");
    fusion::MirrorCheckSettings& m = params.mirror_check;
    m.enabled = reader.boolean("enabled", m.enabled);
    m.gate_deg = reader.number("gate_deg", m.gate_deg);
    m.min_separation_deg = reader.number("min_separation_deg", m.min_separation_deg);
    m.evidence_ratio = reader.number("evidence_ratio", m.evidence_ratio);
    m.floor_deg = reader.number("floor_deg", m.floor_deg);
    m.min_sectors = reader.integer("min_sectors", m.min_sectors);
    m.min_sector_doas = reader.number("min_sector_doas", m.min_sector_doas);
    m.sectors = reader.integer("sectors", m.sectors);
    m.window_s = reader.number("window_s", m.window_s);
    m.judge_doas = reader.integer("judge_doas", m.judge_doas);
    m.symmetry_tolerance = reader.number("symmetry_tolerance", m.symmetry_tolerance);
    m.min_other_arrays = reader.integer("min_other_arrays", m.min_other_arrays);
    m.max_track_angle_deg = reader.number("max_track_angle_deg", m.max_track_angle_deg);
    m.rewarn_s = reader.number("rewarn_s", m.rewarn_s);
  }
  if (section.has("classifier")) {
    // Keys, units and defaults: docs/classification.md.
    ObjectReader reader = section.object("classifier");
    fusion::ClassifierSettings& c = params.classifier;
    c.drone_min_fundamental_hz =
        reader.number("drone_min_fundamental_hz", c.drone_min_fundamental_hz);
    c.drone_max_fundamental_hz =
        reader.number("drone_max_fundamental_hz", c.drone_max_fundamental_hz);
    c.drone_min_comb_persistence =
        reader.number("drone_min_comb_persistence", c.drone_min_comb_persistence);
    c.acoustic_memory_s = reader.number("acoustic_memory_s", c.acoustic_memory_s);
    c.min_acoustic_votes = reader.number("min_acoustic_votes", c.min_acoustic_votes);
    c.undecided_s = reader.number("undecided_s", c.undecided_s);
    c.drone_enter_share = reader.number("drone_enter_share", c.drone_enter_share);
    c.drone_leave_share = reader.number("drone_leave_share", c.drone_leave_share);
    c.kinematic_memory_s = reader.number("kinematic_memory_s", c.kinematic_memory_s);
    c.ground_max_altitude_m = reader.number("ground_max_altitude_m", c.ground_max_altitude_m);
    c.ground_max_altitude_std_m =
        reader.number("ground_max_altitude_std_m", c.ground_max_altitude_std_m);
    c.static_max_speed_mps = reader.number("static_max_speed_mps", c.static_max_speed_mps);
    c.static_long_s = reader.number("static_long_s", c.static_long_s);
    c.static_ground_max_altitude_m =
        reader.number("static_ground_max_altitude_m", c.static_ground_max_altitude_m);
    c.ground_static_s = reader.number("ground_static_s", c.ground_static_s);
    c.aircraft_min_altitude_m = reader.number("aircraft_min_altitude_m", c.aircraft_min_altitude_m);
    c.aircraft_min_speed_mps = reader.number("aircraft_min_speed_mps", c.aircraft_min_speed_mps);
  }
  check_fusion_params(params, section.path(), section.diagnostics());
}

}  // namespace dronetrack::config
