// The Prometheus text writer against known bodies, the checker the e2e tests use against bodies
// it must refuse, and /metrics on a metrics-only server (a node's listener) over loopback.

#include "http_api/metrics_text.hpp"
#include "http_api/http_server.hpp"
#include "tests/http_api/exposition_checker.hpp"

#include <gtest/gtest.h>
// After our headers: <httplib.h> pulls in <resolv.h>, whose `_res` macro breaks Eigen.
#include <httplib.h>

#include <stdexcept>

namespace dronetrack::http_api::metrics_text_test {
namespace {

using ::dronetrack::test::check_exposition;
using Type = MetricsText::Type;

TEST(MetricsText, WritesFamiliesWithEscapedLabels) {
  MetricsText out;
  out.family("dronetrack_test_total", Type::counter, "A help with a \\ backslash\nand a newline");
  out.sample("dronetrack_test_total", 12.0, {{"array", "A\"1\\x\ny"}});
  out.sample("dronetrack_test_total", 0.25, {{"array", "B2"}, {"reason", "late"}});
  out.family("dronetrack_level", Type::gauge, "plain");
  out.sample("dronetrack_level", -1.5e-7);
  EXPECT_EQ(out.text(),
            "# HELP dronetrack_test_total A help with a \\\\ backslash\\nand a newline\n"
            "# TYPE dronetrack_test_total counter\n"
            "dronetrack_test_total{array=\"A\\\"1\\\\x\\ny\"} 12\n"
            "dronetrack_test_total{array=\"B2\",reason=\"late\"} 0.25\n"
            "# HELP dronetrack_level plain\n"
            "# TYPE dronetrack_level gauge\n"
            "dronetrack_level -1.5e-07\n");
  const auto parsed = check_exposition(out.text());
  EXPECT_TRUE(parsed.ok()) << parsed.problems.front();
  EXPECT_EQ(parsed.value("dronetrack_test_total{array=\"B2\",reason=\"late\"}"), 0.25);
}

TEST(MetricsText, HistogramBucketsAreCumulativeWithInfEqualToCount) {
  Histogram histogram({0.125, 0.5, 1.0});  // binary fractions: exact sums
  for (double v : {0.0625, 0.25, 0.25, 7.0, 0.125}) histogram.observe(v);
  MetricsText out;
  out.family("latency_seconds", Type::histogram, "h");
  out.histogram("latency_seconds", histogram, {{"role", "x"}});
  EXPECT_EQ(out.text(),
            "# HELP latency_seconds h\n# TYPE latency_seconds histogram\n"
            "latency_seconds_bucket{role=\"x\",le=\"0.125\"} 2\n"
            "latency_seconds_bucket{role=\"x\",le=\"0.5\"} 4\n"
            "latency_seconds_bucket{role=\"x\",le=\"1\"} 4\n"
            "latency_seconds_bucket{role=\"x\",le=\"+Inf\"} 5\n"
            "latency_seconds_sum{role=\"x\"} 7.6875\n"
            "latency_seconds_count{role=\"x\"} 5\n");
  EXPECT_TRUE(check_exposition(out.text()).ok());
}

TEST(MetricsText, RefusesInvalidNames) {
  MetricsText out;
  EXPECT_THROW(out.family("9lives", Type::gauge, "h"), std::invalid_argument);
  EXPECT_THROW(out.family("has-dash", Type::gauge, "h"), std::invalid_argument);
  out.family("ok", Type::gauge, "h");
  EXPECT_THROW(out.sample("ok", 1.0, {{"__reserved", "x"}}), std::invalid_argument);
  EXPECT_THROW(out.sample("ok", 1.0, {{"a:b", "x"}}), std::invalid_argument);
  EXPECT_THROW(Histogram({1.0, 1.0}), std::invalid_argument);
  EXPECT_TRUE(valid_metric_name("a:b_c9"));
  EXPECT_FALSE(valid_label_name("a:b"));
  EXPECT_EQ(format_sample_value(1.0 / 0.0), "+Inf");
}

// The checker must be able to fail: each body breaks one rule.
TEST(ExpositionChecker, RefusesBrokenBodies) {
  const char* broken[] = {
      "x 1\n",                                       // no TYPE
      "# TYPE x gauge\nx{a=\"b\\q\"} 1\n",           // bad escape
      "# TYPE x gauge\nx one\n",                     // bad value
      "# TYPE x gauge\nx 1",                         // no final newline
      "# TYPE x gauge\n# TYPE y gauge\ny 1\nx 2\n",  // x not contiguous
      "# TYPE h histogram\nh_bucket{le=\"1\"} 3\nh_bucket{le=\"+Inf\"} 2\nh_count 2\n",
      "# TYPE h histogram\nh_bucket{le=\"1\"} 1\nh_bucket{le=\"+Inf\"} 2\nh_count 3\n",
      "# TYPE h histogram\nh_bucket{le=\"1\"} 1\nh_count 1\n",  // no +Inf
  };
  for (const char* body : broken) EXPECT_FALSE(check_exposition(body).ok()) << body;
}

TEST(MetricsEndpoint, MetricsOnlyServerServesTextAndNothingElse) {
  HttpOptions options;
  options.bind = "127.0.0.1:0";
  int scrapes = 0;
  options.metrics = [&scrapes] {
    MetricsText out;
    out.family("scrapes_total", Type::counter, "scrapes");
    out.sample("scrapes_total", ++scrapes);
    return out.text();
  };
  HttpServer server(options);
  server.start();
  httplib::Client client("127.0.0.1", server.port());
  auto first = client.Get("/metrics");
  ASSERT_TRUE(first);
  EXPECT_EQ(first->status, 200);
  EXPECT_EQ(first->get_header_value("Content-Type"), kMetricsContentType);
  EXPECT_EQ(first->body,
            "# HELP scrapes_total scrapes\n# TYPE scrapes_total counter\n"
            "scrapes_total 1\n");
  EXPECT_EQ(client.Get("/metrics")->body.back(), '\n');
  EXPECT_EQ(client.Get("/metrics?x=1")->status, 400);
  EXPECT_EQ(client.Get("/api/tracks")->status, 404);
  EXPECT_EQ(client.Get("/")->status, 404);
  EXPECT_EQ(client.Post("/metrics", "", "text/plain")->status, 405);
  server.stop();
  // Beyond loopback without TLS and users: refused, as the page's server is.
  HttpOptions exposed = options;
  exposed.bind = "0.0.0.0:0";
  HttpServer refused(exposed);
  EXPECT_THROW(refused.start(), std::runtime_error);
}

}  // namespace
}  // namespace dronetrack::http_api::metrics_text_test
