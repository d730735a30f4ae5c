#pragma once
// One x-y chart as inline SVG: axes with ticks and unit labels, a legend, lines or points per
// series. Plain string building: no script, no style sheet, no URL. Every coordinate lands
// inside the viewBox (data are scaled into the plot area; non-finite points are skipped).
#include <string>
#include <vector>

namespace dronetrack::plot {

struct Series {
  std::string label;  // legend text
  std::vector<double> x;
  std::vector<double> y;  // same length as x
  bool dashed = false;    // truth is drawn dashed
  bool points = false;    // dots instead of a line (DOAs, errors)
  int colour = -1;        // palette index; -1: the series' own position
};

struct Chart {
  std::string title;
  std::string x_label;  // with its unit, e.g. "x east (m)"
  std::string y_label;
  std::vector<Series> series;
  bool equal_scale = false;  // a metre is as long on both axes (plan views)
};

inline constexpr int kChartWidth = 960;
inline constexpr int kChartHeight = 440;

// <svg ...>...</svg>, kChartWidth x kChartHeight user units. A chart without data says so.
std::string render_svg(const Chart& chart);

// Text for XML content and attribute values.
std::string escape_xml(const std::string& text);

// Ticks at 1, 2 or 5 x 10^k covering [low, high], about `target` of them.
std::vector<double> nice_ticks(double low, double high, int target);

}  // namespace dronetrack::plot
