#include <string>

#include "config/parse_sections.hpp"

using dronetrack::doa::HarmonicCombSettings;

namespace dronetrack::config {

namespace {

// "doa.acoustic": the per-source features for the classifier (docs/classification.md).
void parse_acoustic_settings(ObjectReader& section, doa::AcousticSettings& settings) {
  Diagnostics& diagnostics = section.diagnostics();
  settings.enabled = section.boolean("enabled", settings.enabled);
  if (const auto band = section.numbers("band_hz", 2, false)) {
    settings.band_hz = {(*band)[0], (*band)[1]};
    if (!(settings.band_hz.low_hz >= 0.0 && settings.band_hz.high_hz > settings.band_hz.low_hz))
      diagnostics.error(section.path_of("band_hz"), "expected 0 <= low_hz < high_hz");
  }
  settings.analysis_every_frames =
      section.integer("analysis_every_frames", settings.analysis_every_frames, 1, 100);
  settings.comb_memory_s = section.number("comb_memory_s", settings.comb_memory_s, 0.05, 60.0);
  settings.history_s = section.number("history_s", settings.history_s, 0.2, 60.0);
  settings.min_bin_coherence =
      section.number("min_bin_coherence", settings.min_bin_coherence, 0.0, 1.0);
  settings.line_direction_tolerance_deg = section.number(
      "line_direction_tolerance_deg", settings.line_direction_tolerance_deg, 0.0, 30.0);
  HarmonicCombSettings& comb = settings.comb;
  comb.min_fundamental_hz =
      section.number("min_fundamental_hz", comb.min_fundamental_hz, 5.0, 5000.0);
  comb.max_fundamental_hz =
      section.number("max_fundamental_hz", comb.max_fundamental_hz, 10.0, 10000.0);
  if (!(comb.max_fundamental_hz > comb.min_fundamental_hz))
    diagnostics.error(section.path_of("max_fundamental_hz"), "must exceed min_fundamental_hz");
  comb.min_strength = section.number("min_comb_strength", comb.min_strength, 0.0, 1.0);
  comb.min_harmonics = section.integer("min_harmonics", comb.min_harmonics, 2, 100);
}

// "doa.static_look": one more look on the frames' averaged phasors (doa/static_source_look.hpp).
void parse_static_look_settings(ObjectReader& section, doa::StaticLookSettings& settings) {
  settings.enabled = section.boolean("enabled", settings.enabled);
  settings.averaging_time_s =
      section.number("averaging_time_s", settings.averaging_time_s, 0.01, 10.0);
  settings.max_drift_deg = section.number("max_drift_deg", settings.max_drift_deg, 0.05, 10.0);
  settings.hold_s = section.number("hold_s", settings.hold_s, 0.1, 10.0);
  settings.own_look_memory_s =
      section.number("own_look_memory_s", settings.own_look_memory_s, 0.0, 10.0);
  settings.min_elevation_deg =
      section.number("min_elevation_deg", settings.min_elevation_deg, -90.0, 90.0);
  settings.max_looks = section.integer("max_looks", settings.max_looks, 1, 8);
  settings.search_every_frames =
      section.integer("search_every_frames", settings.search_every_frames, 1, 100);
}

}  // namespace

// Keys, units and defaults: docs/doa.md ("Configuration").
void parse_doa_params(ObjectReader& section, doa::DoaParams& params) {
  Diagnostics& diagnostics = section.diagnostics();
  if (section.has("bands_hz")) {
    params.bands_hz.clear();
    section.for_each("bands_hz", false, [&](const nlohmann::json& node, const std::string& path) {
      if (!node.is_array() || node.size() != 2 || !node[0].is_number() || !node[1].is_number()) {
        diagnostics.error(path, "expected [low_hz, high_hz], got " + describe_json_type(node));
        return;
      }
      doa::FrequencyBand band{node[0].get<double>(), node[1].get<double>()};
      if (!(band.low_hz >= 0.0 && band.high_hz > band.low_hz)) {
        diagnostics.error(path, "expected 0 <= low_hz < high_hz");
        return;
      }
      if (band.high_hz > 5e5) {
        diagnostics.error(path,
                          "high_hz above 500 kHz, the Nyquist frequency of the fastest "
                          "sample rate dronetrack takes (1 MHz)");
        return;
      }
      params.bands_hz.push_back(band);
    });
    if (params.bands_hz.empty())
      diagnostics.error(section.path_of("bands_hz"), "needs at least one band");
  }
  params.per_band_detection = section.boolean("per_band_detection", params.per_band_detection);
  params.frame_s = section.number("frame_s", params.frame_s, 0.005, 2.0);
  params.hop_s = section.number("hop_s", params.hop_s, 0.001, 2.0);
  if (params.hop_s > params.frame_s) {
    diagnostics.error(section.path_of("hop_s"), "must not exceed frame_s");
  }
  const std::string tracker =
      section.choice("tdoa_tracker", "robust_regression",
                     {"per_frame", "bayesian_grid", "multi_peak", "robust_regression"});
  if (tracker == "per_frame") params.tdoa_tracker = doa::TdoaTracker::per_frame;
  if (tracker == "bayesian_grid") params.tdoa_tracker = doa::TdoaTracker::bayesian_grid;
  if (tracker == "multi_peak") params.tdoa_tracker = doa::TdoaTracker::multi_peak;
  if (tracker == "robust_regression") params.tdoa_tracker = doa::TdoaTracker::robust_regression;
  params.max_sources = section.integer("max_sources", params.max_sources, 1, 8);
  params.detection_snr_db =
      section.number("detection_snr_db", params.detection_snr_db, -20.0, 60.0);

  params.min_gcc_peak = section.number("min_gcc_peak", params.min_gcc_peak, 0.0, 1.0);
  params.noise_floor_rise_db_per_s =
      section.number("noise_floor_rise_db_per_s", params.noise_floor_rise_db_per_s, 0.01, 100.0);
  params.max_clipped_fraction =
      section.number("max_clipped_fraction", params.max_clipped_fraction, 0.0, 1.0);
  const std::string interpolation =
      section.choice("lag_interpolation", "band_limited", {"band_limited", "parabolic"});
  params.lag_interpolation = interpolation == "parabolic" ? doa::LagInterpolation::parabolic
                                                          : doa::LagInterpolation::band_limited;
  params.correlation_oversample =
      section.integer("correlation_oversample", params.correlation_oversample, 1, 16);
  params.max_angular_rate_dps =
      section.number("max_angular_rate_dps", params.max_angular_rate_dps, 1.0, 3600.0);
  params.regression_window_frames =
      section.integer("regression_window_frames", params.regression_window_frames, 5, 64);
  params.regression_delay_frames =
      section.integer("regression_delay_frames", params.regression_delay_frames, 0, 63);
  if (params.regression_delay_frames >= params.regression_window_frames)
    diagnostics.error(section.path_of("regression_delay_frames"),
                      "must be less than regression_window_frames");
  params.max_norm_error = section.number("max_norm_error", params.max_norm_error, 0.001, 1.0);
  params.max_chi2_per_dof = section.number("max_chi2_per_dof", params.max_chi2_per_dof, 1.0, 1e6);
  params.srp_grid_deg = section.number("srp_grid_deg", params.srp_grid_deg, 0.5, 30.0);
  params.srp_min_separation_deg =
      section.number("srp_min_separation_deg", params.srp_min_separation_deg, 1.0, 90.0);
  params.srp_min_power_sigmas =
      section.number("srp_min_power_sigmas", params.srp_min_power_sigmas, 0.0, 100.0);
  params.min_elevation_deg =
      section.number("min_elevation_deg", params.min_elevation_deg, -90.0, 90.0);
  params.snr_weighting = section.boolean("snr_weighting", params.snr_weighting);
  params.snr_noise_rise_db_per_s =
      section.number("snr_noise_rise_db_per_s", params.snr_noise_rise_db_per_s, 0.01, 100.0);
  params.snr_weight_floor = section.number("snr_weight_floor", params.snr_weight_floor, 0.0, 1.0);
  params.ground_echo = section.boolean("ground_echo", params.ground_echo);
  params.ground_height_m =
      section.number("ground_height_m", params.ground_height_m, -10000.0, 10000.0);
  params.own_comb_bins = section.boolean("own_comb_bins", params.own_comb_bins);
  params.follow_source_tracks =
      section.boolean("follow_source_tracks", params.follow_source_tracks);
  params.free_look_lobe_choice =
      section.boolean("free_look_lobe_choice", params.free_look_lobe_choice);
  params.comb_look = section.boolean("comb_look", params.comb_look);
  params.static_null = section.boolean("static_null", params.static_null);
  params.static_null_learn_s =
      section.number("static_null_learn_s", params.static_null_learn_s, 0.2, 600.0);
  params.static_null_forget_s =
      section.number("static_null_forget_s", params.static_null_forget_s, 0.1, 600.0);
  params.static_null_max_elevation_deg = section.number(
      "static_null_max_elevation_deg", params.static_null_max_elevation_deg, -90.0, 90.0);
  params.static_null_tolerance_us =
      section.number("static_null_tolerance_us", params.static_null_tolerance_us, 0.1, 1000.0);
  params.static_null_max_sources =
      section.integer("static_null_max_sources", params.static_null_max_sources, 0, 4);
  params.static_null_cancel = section.boolean("static_null_cancel", params.static_null_cancel);
  params.static_null_cancel_refill =
      section.boolean("static_null_cancel_refill", params.static_null_cancel_refill);
  params.static_null_cancel_min_residual_over_noise =
      section.number("static_null_cancel_min_residual_over_noise",
                     params.static_null_cancel_min_residual_over_noise, 0.0, 1000.0);
  if (section.has("static_look")) {
    ObjectReader static_look = section.object("static_look");
    parse_static_look_settings(static_look, params.static_look);
  }
  if (section.has("acoustic")) {
    ObjectReader acoustic = section.object("acoustic");
    parse_acoustic_settings(acoustic, params.acoustic);
  }
}

}  // namespace dronetrack::config
