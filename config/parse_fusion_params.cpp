#include <string>

#include "config/parse_sections.hpp"

namespace dronetrack::config {

void parse_fusion_params(ObjectReader& section, fusion::FusionParams& params) {
  const std::string filter =
      section.choice("filter", "ukf", {"ukf", "ukf_seed002", "ekf", "particle"});
  if (filter == "ukf") params.filter = fusion::FilterKind::ukf;
  if (filter == "ukf_seed002") params.filter = fusion::FilterKind::ukf_seed002;
  if (filter == "ekf") params.filter = fusion::FilterKind::ekf;
  if (filter == "particle") params.filter = fusion::FilterKind::particle;
  params.jerk_noise_std_mps3 =
      section.number("jerk_noise_std_mps3", params.jerk_noise_std_mps3, 1e-6, 1e4);
  params.output_rate_hz = section.number("output_rate_hz", params.output_rate_hz, 0.1, 1000.0);
  params.reorder_window_s = section.number("reorder_window_s", params.reorder_window_s, 0.0, 10.0);
  params.gate_probability =
      section.number("gate_probability", params.gate_probability, 0.5, 0.999999);
  params.confirm_hits = section.integer("confirm_hits", params.confirm_hits, 1, 1000);
  params.confirm_window = section.integer("confirm_window", params.confirm_window, 1, 1000);
  if (params.confirm_hits > params.confirm_window) {
    section.diagnostics().error(section.path_of("confirm_hits"), "must not exceed confirm_window");
  }
  params.coast_timeout_s = section.number("coast_timeout_s", params.coast_timeout_s, 0.1, 600.0);
}

}  // namespace dronetrack::config
