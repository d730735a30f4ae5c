#include "plot/figures.hpp"

#include <map>
#include <utility>

#include "doa/array_geometry.hpp"

namespace dronetrack::plot {
namespace {

// Track lines grouped by id, in time order (the lines come in time order).
std::map<int, std::vector<const eval::TrackRecord*>> by_track(
    const std::vector<eval::TrackRecord>& tracks) {
  std::map<int, std::vector<const eval::TrackRecord*>> out;
  for (const auto& track : tracks) out[track.id].push_back(&track);
  return out;
}

std::string track_label(int id) { return "track " + std::to_string(id); }

}  // namespace

std::vector<Chart> track_charts(const std::vector<eval::TrackRecord>& tracks,
                                const eval::Truth* truth) {
  Chart plan{"Plan view", "x east (m)", "y north (m)", {}, true};
  Chart altitude{"Altitude over time", "time (s)", "z up (m)", {}, false};
  int colour = 0;
  for (const auto& [id, lines] : by_track(tracks)) {
    Series xy{track_label(id), {}, {}, false, false, colour};
    Series tz{track_label(id), {}, {}, false, false, colour};
    for (const auto* line : lines) {
      xy.x.push_back(line->position_m.x());
      xy.y.push_back(line->position_m.y());
      tz.x.push_back(line->time_s);
      tz.y.push_back(line->position_m.z());
    }
    plan.series.push_back(std::move(xy));
    altitude.series.push_back(std::move(tz));
    ++colour;
  }
  if (truth != nullptr) {
    int shade = 0;
    for (const auto& source : truth->sources) {
      const int truth_colour = shade++ % 2 == 0 ? 6 : 8;  // dashed black, then dashed grey
      Series xy{"truth " + source.id, {}, {}, true, false, truth_colour};
      Series tz{"truth " + source.id, {}, {}, true, false, truth_colour};
      for (std::size_t i = 0; i < source.time_s.size(); ++i) {
        xy.x.push_back(source.position_m[i].x());
        xy.y.push_back(source.position_m[i].y());
        tz.x.push_back(source.time_s[i]);
        tz.y.push_back(source.position_m[i].z());
      }
      plan.series.push_back(std::move(xy));
      altitude.series.push_back(std::move(tz));
    }
  }
  return {plan, altitude};
}

Chart error_chart(const eval::EvalReport& report) {
  Chart chart{"3-D error over time (track against the truth it was assigned to)",
              "time (s)",
              "error (m)",
              {},
              false};
  int colour = 0;
  for (const auto& source : report.sources) {
    std::map<int, Series> per_track;
    for (const auto& sample : source.errors) {
      auto [it, added] = per_track.try_emplace(sample.track_id);
      if (added) {
        it->second.label = source.id + ": " + track_label(sample.track_id);
        it->second.points = true;
      }
      it->second.x.push_back(sample.time_s);
      it->second.y.push_back(sample.error_m);
    }
    for (auto& [id, series] : per_track) {
      series.colour = colour++;
      chart.series.push_back(std::move(series));
    }
  }
  return chart;
}

Chart doa_error_chart(const eval::EvalReport& report) {
  Chart chart{"DOA error over time, per array", "time (s)", "angular error (deg)", {}, false};
  for (const auto& array : report.doa) {
    chart.series.push_back({"array " + array.array, array.time_s, array.error_deg, false, true});
  }
  return chart;
}

std::vector<Chart> doa_charts(const std::vector<eval::DoaRecord>& doas) {
  Chart azimuth{"DOA azimuth over time, per array",
                "time (s)",
                "azimuth (deg, counter-clockwise from east)",
                {},
                false};
  Chart elevation{"DOA elevation over time, per array", "time (s)", "elevation (deg)", {}, false};
  std::map<std::string, std::pair<Series, Series>> per_array;
  for (const auto& doa : doas) {
    auto [it, added] = per_array.try_emplace(doa.array);
    if (added) {
      it->second.first = {"array " + doa.array, {}, {}, false, true};
      it->second.second = {"array " + doa.array, {}, {}, false, true};
    }
    const Eigen::Vector3d u = doa.direction.normalized();
    it->second.first.x.push_back(doa.time_s);
    it->second.first.y.push_back(doa::azimuth_deg(u));
    it->second.second.x.push_back(doa.time_s);
    it->second.second.y.push_back(doa::elevation_deg(u));
  }
  for (auto& [id, series] : per_array) {
    azimuth.series.push_back(std::move(series.first));
    elevation.series.push_back(std::move(series.second));
  }
  return {azimuth, elevation};
}

std::string html_page(const std::string& title, const std::vector<std::string>& notes,
                      const std::vector<Chart>& charts) {
  std::string html;
  html.append("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>")
      .append(escape_xml(title))
      .append("</title>\n</head>\n<body style=\"font-family: sans-serif; margin: 16px;\">\n<h1>")
      .append(escape_xml(title))
      .append("</h1>\n");
  for (const auto& note : notes) html.append("<p>").append(escape_xml(note)).append("</p>\n");
  for (const auto& chart : charts) {
    html.append("<figure style=\"margin: 16px 0;\">\n").append(render_svg(chart));
    html.append("</figure>\n");
  }
  html.append("</body>\n</html>\n");
  return html;
}

}  // namespace dronetrack::plot
