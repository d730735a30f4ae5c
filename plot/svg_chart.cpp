#include "plot/svg_chart.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace dronetrack::plot {
namespace {

// Distinguishable on white and for the common colour-vision deficiencies (Okabe-Ito, then
// darker tones).
constexpr const char* kPalette[] = {"#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00",
                                    "#56B4E9", "#000000", "#8C564B", "#7F7F7F", "#BCBD22"};
constexpr int kPaletteSize = sizeof(kPalette) / sizeof(kPalette[0]);

constexpr double kLeft = 70.0;                     // room for the y tick labels and the y label
constexpr double kRight = 210.0;                   // the legend
constexpr double kTop = 34.0;                      // the title
constexpr double kBottom = 52.0;                   // x tick labels and the x label
constexpr std::size_t kMaxPointsPerSeries = 4000;  // a long run is thinned evenly

std::string number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.1f", value);
  return buffer;
}

std::string tick_text(double value, double step) {
  char buffer[32];
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  std::snprintf(buffer, sizeof buffer, "%.*f", std::min(decimals, 6), value == 0.0 ? 0.0 : value);
  return buffer;
}

struct Range {
  double low = std::numeric_limits<double>::infinity();
  double high = -std::numeric_limits<double>::infinity();
  void add(double v) {
    low = std::min(low, v);
    high = std::max(high, v);
  }
  bool empty() const { return !(high >= low); }
  void pad() {
    if (empty()) {
      low = 0.0;
      high = 1.0;
    }
    const double span = high - low;
    const double margin = span > 0.0 ? 0.04 * span : std::max(1.0, std::fabs(low) * 0.1);
    low -= margin;
    high += margin;
  }
};

}  // namespace

std::string escape_xml(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out.append("&amp;");
        break;
      case '<':
        out.append("&lt;");
        break;
      case '>':
        out.append("&gt;");
        break;
      case '"':
        out.append("&quot;");
        break;
      default:
        out.push_back(c);
    }
  }
  return out;
}

std::vector<double> nice_ticks(double low, double high, int target) {
  std::vector<double> ticks;
  if (!(high > low) || target < 1) return ticks;
  const double raw = (high - low) / target;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double factor : {1.0, 2.0, 5.0, 10.0}) {
    step = factor * magnitude;
    if (step >= raw) break;
  }
  for (double v = std::ceil(low / step) * step; v <= high + 1e-9 * step; v += step) {
    ticks.push_back(std::fabs(v) < 1e-12 * step ? 0.0 : v);
  }
  return ticks;
}

std::string render_svg(const Chart& chart) {
  const double width = kChartWidth;
  const double height = kChartHeight;
  const double plot_w = width - kLeft - kRight;
  const double plot_h = height - kTop - kBottom;

  Range xr, yr;
  for (const Series& s : chart.series) {
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      xr.add(s.x[i]);
      yr.add(s.y[i]);
    }
  }
  const bool no_data = xr.empty();
  xr.pad();
  yr.pad();
  if (chart.equal_scale) {
    // Widen the narrower axis so a metre has one length on screen.
    const double per_px = std::max((xr.high - xr.low) / plot_w, (yr.high - yr.low) / plot_h);
    const double xc = 0.5 * (xr.low + xr.high);
    const double yc = 0.5 * (yr.low + yr.high);
    xr = {xc - 0.5 * per_px * plot_w, xc + 0.5 * per_px * plot_w};
    yr = {yc - 0.5 * per_px * plot_h, yc + 0.5 * per_px * plot_h};
  }
  const auto sx = [&](double x) { return kLeft + (x - xr.low) / (xr.high - xr.low) * plot_w; };
  const auto sy = [&](double y) {
    return kTop + plot_h - (y - yr.low) / (yr.high - yr.low) * plot_h;
  };

  std::string svg;
  // Inline in HTML: no namespace attribute needed, so the file names no URL at all.
  svg.append("<svg viewBox=\"0 0 ")
      .append(std::to_string(kChartWidth))
      .append(" ")
      .append(std::to_string(kChartHeight))
      .append("\" width=\"")
      .append(std::to_string(kChartWidth))
      .append("\" height=\"")
      .append(std::to_string(kChartHeight))
      .append("\" role=\"img\" font-family=\"sans-serif\" font-size=\"12\">\n");
  svg.append("<title>").append(escape_xml(chart.title)).append("</title>\n");
  svg.append("<rect x=\"0\" y=\"0\" width=\"")
      .append(std::to_string(kChartWidth))
      .append("\" height=\"")
      .append(std::to_string(kChartHeight))
      .append("\" fill=\"white\"/>\n");
  svg.append("<text x=\"")
      .append(number(kLeft))
      .append("\" y=\"20\" font-size=\"14\" font-weight=\"bold\">")
      .append(escape_xml(chart.title))
      .append("</text>\n");

  // Grid and ticks.
  const std::vector<double> xticks = nice_ticks(xr.low, xr.high, 8);
  const double xstep = xticks.size() > 1 ? xticks[1] - xticks[0] : 1.0;
  for (double t : xticks) {
    const std::string x = number(sx(t));
    svg.append("<line x1=\"").append(x).append("\" y1=\"").append(number(kTop));
    svg.append("\" x2=\"").append(x).append("\" y2=\"").append(number(kTop + plot_h));
    svg.append("\" stroke=\"#e0e0e0\"/>\n");
    svg.append("<text x=\"").append(x).append("\" y=\"").append(number(kTop + plot_h + 16));
    svg.append("\" text-anchor=\"middle\">").append(tick_text(t, xstep)).append("</text>\n");
  }
  const std::vector<double> yticks = nice_ticks(yr.low, yr.high, 6);
  const double ystep = yticks.size() > 1 ? yticks[1] - yticks[0] : 1.0;
  for (double t : yticks) {
    const std::string y = number(sy(t));
    svg.append("<line x1=\"").append(number(kLeft)).append("\" y1=\"").append(y);
    svg.append("\" x2=\"").append(number(kLeft + plot_w)).append("\" y2=\"").append(y);
    svg.append("\" stroke=\"#e0e0e0\"/>\n");
    svg.append("<text x=\"").append(number(kLeft - 6)).append("\" y=\"").append(number(sy(t) + 4));
    svg.append("\" text-anchor=\"end\">").append(tick_text(t, ystep)).append("</text>\n");
  }
  svg.append("<rect x=\"").append(number(kLeft)).append("\" y=\"").append(number(kTop));
  svg.append("\" width=\"").append(number(plot_w)).append("\" height=\"").append(number(plot_h));
  svg.append("\" fill=\"none\" stroke=\"#333\"/>\n");
  svg.append("<text x=\"")
      .append(number(kLeft + 0.5 * plot_w))
      .append("\" y=\"")
      .append(number(height - 12))
      .append("\" text-anchor=\"middle\">")
      .append(escape_xml(chart.x_label))
      .append("</text>\n");
  svg.append("<text transform=\"translate(16 ")
      .append(number(kTop + 0.5 * plot_h))
      .append(") rotate(-90)\" text-anchor=\"middle\">")
      .append(escape_xml(chart.y_label))
      .append("</text>\n");
  if (no_data) {
    svg.append("<text x=\"")
        .append(number(kLeft + 0.5 * plot_w))
        .append("\" y=\"")
        .append(number(kTop + 0.5 * plot_h))
        .append("\" text-anchor=\"middle\">no data</text>\n");
  }

  // Series, then the legend beside the plot area.
  for (std::size_t k = 0; k < chart.series.size(); ++k) {
    const Series& s = chart.series[k];
    const char* colour = kPalette[(s.colour >= 0 ? s.colour : static_cast<int>(k)) % kPaletteSize];
    const std::size_t n = std::min(s.x.size(), s.y.size());
    const std::size_t stride =
        std::max<std::size_t>(1, (n + kMaxPointsPerSeries - 1) / kMaxPointsPerSeries);
    svg.append("<g><title>").append(escape_xml(s.label)).append("</title>\n");
    std::string path;
    for (std::size_t i = 0; i < n; i += stride) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      const std::string px = number(sx(s.x[i]));
      const std::string py = number(sy(s.y[i]));
      if (s.points) {
        svg.append("<circle cx=\"").append(px).append("\" cy=\"").append(py);
        svg.append("\" r=\"1.6\" fill=\"").append(colour).append("\"/>");
      } else {
        path.append(path.empty() ? "M" : " L").append(px).append(" ").append(py);
      }
    }
    if (!path.empty()) {
      svg.append("<path d=\"").append(path).append("\" fill=\"none\" stroke=\"").append(colour);
      svg.append("\" stroke-width=\"1.5\"");
      if (s.dashed) svg.append(" stroke-dasharray=\"6 4\"");
      svg.append("/>");
    }
    svg.append("</g>\n");
    const double ly = kTop + 8.0 + 18.0 * static_cast<double>(k);
    if (ly > height - 10.0) continue;  // more series than room: the tooltip still names them
    const double lx = kLeft + plot_w + 14.0;
    svg.append("<line x1=\"").append(number(lx)).append("\" y1=\"").append(number(ly));
    svg.append("\" x2=\"").append(number(lx + 22)).append("\" y2=\"").append(number(ly));
    svg.append("\" stroke=\"")
        .append(colour)
        .append("\" stroke-width=\"")
        .append(s.points ? "4" : "2");
    svg.append(s.dashed ? "\" stroke-dasharray=\"6 4\"/>" : "\"/>");
    svg.append("<text x=\"").append(number(lx + 28)).append("\" y=\"").append(number(ly + 4));
    svg.append("\">").append(escape_xml(s.label)).append("</text>\n");
  }
  svg.append("</svg>\n");
  return svg;
}

}  // namespace dronetrack::plot
