#include <string>

#include "config/parse_sections.hpp"

namespace dronetrack::config {

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
      params.bands_hz.push_back(band);
    });
    if (params.bands_hz.empty())
      diagnostics.error(section.path_of("bands_hz"), "needs at least one band");
  }
  params.frame_s = section.number("frame_s", params.frame_s, 0.005, 2.0);
  params.hop_s = section.number("hop_s", params.hop_s, 0.001, 2.0);
  if (params.hop_s > params.frame_s) {
    diagnostics.error(section.path_of("hop_s"), "must not exceed frame_s");
  }
  const std::string tracker =
      section.choice("tdoa_tracker", "bayesian_grid",
                     {"per_frame", "bayesian_grid", "multi_peak", "robust_regression"});
  if (tracker == "per_frame") params.tdoa_tracker = doa::TdoaTracker::per_frame;
  if (tracker == "bayesian_grid") params.tdoa_tracker = doa::TdoaTracker::bayesian_grid;
  if (tracker == "multi_peak") params.tdoa_tracker = doa::TdoaTracker::multi_peak;
  if (tracker == "robust_regression") params.tdoa_tracker = doa::TdoaTracker::robust_regression;
  params.max_sources = section.integer("max_sources", params.max_sources, 1, 8);
  params.detection_snr_db =
      section.number("detection_snr_db", params.detection_snr_db, -20.0, 60.0);
}

}  // namespace dronetrack::config
