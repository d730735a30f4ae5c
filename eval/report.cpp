#include "eval/report.hpp"

#include <cstdio>

namespace dronetrack::eval {
namespace {

std::string format(const char* pattern, auto... values) {
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, pattern, values...);
  return buffer;
}

std::string position_row(const std::string& name, const PositionMetrics& m) {
  return format("%-8s %7d %8.3f %8.3f %8.3f %8.3f %8.3f %8.2f %7.2f %7.2f %7.2f\n", name.c_str(),
                m.samples, m.rmse_3d_m, m.median_error_m, m.p90_error_m, m.rmse_horizontal_m,
                m.rmse_vertical_m, m.pfe_total_percent, m.pfe_axis_percent.x(),
                m.pfe_axis_percent.y(), m.pfe_axis_percent.z());
}

nlohmann::json position_json(const PositionMetrics& m) {
  return {{"samples", m.samples},
          {"rmse_3d_m", m.rmse_3d_m},
          {"median_error_m", m.median_error_m},
          {"p90_error_m", m.p90_error_m},
          {"max_error_m", m.max_error_m},
          {"rmse_horizontal_m", m.rmse_horizontal_m},
          {"rmse_vertical_m", m.rmse_vertical_m},
          {"pfe_total_percent", m.pfe_total_percent},
          {"pfe_axis_percent",
           {m.pfe_axis_percent.x(), m.pfe_axis_percent.y(), m.pfe_axis_percent.z()}}};
}

}  // namespace

std::string format_table(const EvalReport& r) {
  std::string out;
  out +=
      format("window %.2f .. %.2f s, tick %.3f s, association gate %.1f m, coverage gate %.1f m\n",
             r.start_s, r.end_s, r.tick_s, r.options.association_gate_m, r.options.coverage_gate_m);
  out +=
      "\nposition samples  rmse3d_m  median_m    p90_m  rmseH_m  rmseV_m    PFE%    PFEx%   PFEy%  "
      " "
      "PFEz%\n";
  for (const SourceMetrics& source : r.sources) out += position_row(source.id, source.position);
  out += position_row("all", r.position);
  out += "\nsource  coverage  id_switches  track_ids\n";
  for (const SourceMetrics& source : r.sources) {
    std::string ids;
    for (int id : source.track_ids) {
      if (!ids.empty()) ids += ',';
      ids += std::to_string(id);
    }
    out += format("%-8s %7.2f%% %12d  %s\n", source.id.c_str(), 100.0 * source.coverage,
                  source.id_switches, ids.empty() ? "-" : ids.c_str());
  }
  out += format("%-8s %7.2f%% %12d\n", "all", 100.0 * r.coverage, r.id_switches);
  out += format(
      "\nsource  travelled_m  final_error_m  converged_after_s  first_tracked_s  one_array_s  "
      "(within %.1f m)\n",
      r.options.converge_gate_m);
  for (const SourceMetrics& source : r.sources) {
    out += format("%-8s %11.1f %14.3f %18.1f %16.1f %12.1f\n", source.id.c_str(),
                  source.travelled_m, source.final_error_m, source.converged_after_s,
                  source.first_tracked_s, source.one_array_time_s);
  }
  out += format(
      "\ntracks %d, track time %.1f s, false-track time %.1f s (%.2f%%), of which near no source "
      "%.1f s (%.2f%%)\n",
      r.tracks_seen, r.track_time_s, r.false_track_time_s, 100.0 * r.false_track_fraction,
      r.ghost_track_time_s, 100.0 * r.ghost_track_fraction);
  out += "\nclass   tracked_s  said_drone  drone_share  classified_after_s\n";
  for (const SourceMetrics& source : r.sources) {
    out += format("%-8s %8.1f %11.1f %11.2f%% %19.1f\n", source.id.c_str(), source.tracked_time_s,
                  source.drone_class_time_s, 100.0 * source.drone_class_share,
                  source.classified_after_s);
  }
  for (const OtherSourceMetrics& other : r.others) {
    out += format("%-8s %8.1f %11.1f   (%s)\n", other.id.c_str(), other.tracked_time_s,
                  other.as_drone_time_s, other.source_class.c_str());
  }
  out += format("non-drone tracks said drone: %.1f s, %.2f%% of the run\n",
                r.non_drone_as_drone_time_s, 100.0 * r.non_drone_as_drone_fraction);
  if (r.alerts_read >= 0) {
    out += format("alerts: %d read; zone entries by drones %d, by other tracks %d\n", r.alerts_read,
                  r.drone_zone_entries, r.non_drone_zone_entries);
  }
  if (!r.doa.empty()) {
    out += "\narray      DOAs  median_deg  p90_deg  mean_deg\n";
    for (const DoaArrayMetrics& doa : r.doa) {
      out += format("%-8s %6d %11.2f %8.2f %9.2f\n", doa.array.c_str(), doa.count,
                    doa.median_error_deg, doa.p90_error_deg, doa.mean_error_deg);
    }
    if (r.doa_unmatched > 0) out += format("(%d DOAs without truth)\n", r.doa_unmatched);
  }
  return out;
}

nlohmann::json to_json(const EvalReport& r) {
  nlohmann::json sources = nlohmann::json::array();
  for (const SourceMetrics& source : r.sources) {
    sources.push_back({{"id", source.id},
                       {"position", position_json(source.position)},
                       {"truth_time_s", source.truth_time_s},
                       {"covered_time_s", source.covered_time_s},
                       {"coverage", source.coverage},
                       {"id_switches", source.id_switches},
                       {"track_ids", source.track_ids},
                       {"tracked_time_s", source.tracked_time_s},
                       {"drone_class_share", source.drone_class_share},
                       {"classified_after_s", source.classified_after_s},
                       {"travelled_m", source.travelled_m},
                       {"final_error_m", source.final_error_m},
                       {"converged_after_s", source.converged_after_s},
                       {"first_tracked_s", source.first_tracked_s},
                       {"one_array_time_s", source.one_array_time_s}});
  }
  nlohmann::json others = nlohmann::json::array();
  for (const OtherSourceMetrics& other : r.others) {
    others.push_back({{"id", other.id},
                      {"class", other.source_class},
                      {"tracked_time_s", other.tracked_time_s},
                      {"as_drone_time_s", other.as_drone_time_s}});
  }
  nlohmann::json doa = nlohmann::json::array();
  for (const DoaArrayMetrics& entry : r.doa) {
    doa.push_back({{"array", entry.array},
                   {"count", entry.count},
                   {"median_error_deg", entry.median_error_deg},
                   {"p90_error_deg", entry.p90_error_deg},
                   {"mean_error_deg", entry.mean_error_deg}});
  }
  return {{"window_s", {r.start_s, r.end_s}},
          {"tick_s", r.tick_s},
          {"association_gate_m", r.options.association_gate_m},
          {"coverage_gate_m", r.options.coverage_gate_m},
          {"converge_gate_m", r.options.converge_gate_m},
          {"array_centroid_m",
           {r.array_centroid_m.x(), r.array_centroid_m.y(), r.array_centroid_m.z()}},
          {"position", position_json(r.position)},
          {"sources", sources},
          {"coverage", r.coverage},
          {"id_switches", r.id_switches},
          {"tracks_seen", r.tracks_seen},
          {"track_time_s", r.track_time_s},
          {"false_track_time_s", r.false_track_time_s},
          {"false_track_fraction", r.false_track_fraction},
          {"ghost_track_time_s", r.ghost_track_time_s},
          {"ghost_track_fraction", r.ghost_track_fraction},
          {"others", others},
          {"non_drone_as_drone_time_s", r.non_drone_as_drone_time_s},
          {"non_drone_as_drone_fraction", r.non_drone_as_drone_fraction},
          {"alerts_read", r.alerts_read},
          {"drone_zone_entries", r.drone_zone_entries},
          {"non_drone_zone_entries", r.non_drone_zone_entries},
          {"doa", doa},
          {"doa_unmatched", r.doa_unmatched}};
}

}  // namespace dronetrack::eval
