// One chart drawn to SVG against known answers: ticks, escaping, equal scale, thinning, and
// every coordinate inside the viewBox whatever the data.
#include "plot/svg_chart.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <regex>
#include <string>

namespace dronetrack::plot {
namespace {

// Every circle centre and path vertex of an SVG.
std::vector<std::pair<double, double>> drawn_points(const std::string& svg) {
  std::vector<std::pair<double, double>> out;
  static const std::regex circle(R"re(cx="(-?[0-9.]+)" cy="(-?[0-9.]+)")re");
  static const std::regex vertex(R"([ML](-?[0-9.]+) (-?[0-9.]+))");
  for (const auto* pattern : {&circle, &vertex}) {
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), *pattern);
         it != std::sregex_iterator(); ++it) {
      out.push_back({std::stod((*it)[1]), std::stod((*it)[2])});
    }
  }
  return out;
}

TEST(SvgChart, NiceTicksAreOneTwoFiveTimesAPowerOfTen) {
  EXPECT_EQ(nice_ticks(0.0, 10.0, 5), (std::vector<double>{0, 2, 4, 6, 8, 10}));
  EXPECT_EQ(nice_ticks(-240.0, 110.0, 8), (std::vector<double>{-200, -150, -100, -50, 0, 50, 100}));
  const auto small = nice_ticks(0.013, 0.061, 4);  // a step of 0.012 rounds up to 0.02
  ASSERT_EQ(small.size(), 3u);
  EXPECT_NEAR(small[0], 0.02, 1e-12);
  EXPECT_NEAR(small[2], 0.06, 1e-12);
  EXPECT_TRUE(nice_ticks(1.0, 1.0, 5).empty());
}

TEST(SvgChart, EscapesTextAndStaysInsideTheViewBox) {
  Chart chart{"A <b> & \"c\"", "x (m)", "y (m)", {}, true};
  Series line{"track <1>", {-500, 0, 1e4}, {3, 4, 5}, false, false};
  Series dots{"array N&1",
              {0, 1, std::nan(""), 2},
              {0, 1, 7, std::numeric_limits<double>::infinity()},
              false,
              true};
  chart.series = {line, dots};
  const std::string svg = render_svg(chart);
  EXPECT_NE(svg.find("A &lt;b&gt; &amp; &quot;c&quot;"), std::string::npos);
  EXPECT_NE(svg.find(">track &lt;1&gt;<"), std::string::npos);
  EXPECT_NE(svg.find(">array N&amp;1<"), std::string::npos);
  EXPECT_EQ(svg.find("http"), std::string::npos);
  const auto points = drawn_points(svg);
  EXPECT_EQ(points.size(), 3u + 2u);  // the non-finite dots are skipped
  for (const auto& [x, y] : points) {
    EXPECT_TRUE(x >= 0 && x <= kChartWidth && y >= 0 && y <= kChartHeight) << x << ", " << y;
  }
}

TEST(SvgChart, EqualScaleGivesAMetreOneLengthOnBothAxes) {
  // A 100 m x 10 m box: with equal scale its drawn width is ten times its height.
  Chart chart{"plan", "x (m)", "y (m)", {{"box", {0, 100, 100, 0, 0}, {0, 0, 10, 10, 0}}}, true};
  const auto points = drawn_points(render_svg(chart));
  ASSERT_EQ(points.size(), 5u);
  const double width = points[1].first - points[0].first;
  const double height = points[1].second - points[2].second;
  EXPECT_NEAR(width / height, 10.0, 0.05);
}

TEST(SvgChart, LongSeriesAreThinnedAndEmptyChartsSaySo) {
  Series many{"many", {}, {}, false, true};
  for (int i = 0; i < 20000; ++i) {
    many.x.push_back(i);
    many.y.push_back(std::sin(i * 0.01));
  }
  const std::string svg = render_svg({"long", "t (s)", "v", {many}, false});
  EXPECT_LE(drawn_points(svg).size(), 4000u);
  EXPECT_GE(drawn_points(svg).size(), 3000u);
  EXPECT_NE(render_svg({"empty", "t (s)", "v", {}, false}).find(">no data<"), std::string::npos);
}

}  // namespace
}  // namespace dronetrack::plot
