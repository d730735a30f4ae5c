// HttpServer over a real loopback socket: each endpoint's JSON, the 4xx paths, static files
// with traversal attempts, bind errors, and Server-Sent Events.

#include "http_api/http_server.hpp"
#include "tests/http_api/test_support.hpp"

#include <gtest/gtest.h>
// After our headers: <httplib.h> pulls in <resolv.h>, whose `_res` macro breaks Eigen.
#include <httplib.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

namespace dronetrack::http_api::http_server_test {
namespace {

using nlohmann::json;
using test::make_track;
using test::two_array_layout;
namespace fs = std::filesystem;

class HttpServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    web_root_ = fs::temp_directory_path() /
                ("dronetrack_http_test_" + std::to_string(::getpid()) + "_" +
                 ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(web_root_);
    fs::create_directories(web_root_ / "sub");
    write(web_root_ / "index.html", "<!doctype html><title>dronetrack</title>");
    write(web_root_ / "app.js", "console.log('hi');");
    write(web_root_ / "sub" / "style.css", "body{}");
    write(web_root_ / ".secret", "HIDDEN-CONTENT");
    write(web_root_.parent_path() / (web_root_.filename().string() + "_outside.txt"),
          "OUTSIDE-CONTENT");
    fs::create_symlink(web_root_.parent_path() / (web_root_.filename().string() + "_outside.txt"),
                       web_root_ / "link.txt");

    state_.publish_tracks(12.0, {make_track(3, 12.0, {20, 20, 35}, {0, 5, 0})});
    doa::NodeStatus status;
    status.array_id = "A1";
    status.time_s = 12.0;
    state_.publish_node(status);
    fusion::ZoneEvent event;
    event.zone = "pad";
    event.track_id = 3;
    event.time_s = 12.0;
    state_.publish_alert(event);

    HttpOptions options;
    options.bind = "127.0.0.1:0";
    options.web_root = web_root_;
    server_ = std::make_unique<HttpServer>(state_, options);
    server_->start();
    ASSERT_GT(server_->port(), 0);
  }
  void TearDown() override {
    server_.reset();
    fs::remove_all(web_root_);
    fs::remove(web_root_.parent_path() / (web_root_.filename().string() + "_outside.txt"));
  }
  static void write(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }
  httplib::Client client() const {
    httplib::Client c("127.0.0.1", server_->port());
    c.set_read_timeout(5, 0);
    return c;
  }
  json get_json(const std::string& path, int expected_status) {
    auto c = client();
    auto res = c.Get(path.c_str());
    EXPECT_TRUE(res) << path;
    if (!res) return {};
    EXPECT_EQ(res->status, expected_status) << path << ": " << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/json") << path;
    return json::parse(res->body);
  }
  // Sends raw bytes (paths a well-behaved client would normalise) and returns the response.
  std::string raw_request(const std::string& request) const {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(server_->port()));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
    EXPECT_EQ(::send(fd, request.data(), request.size(), 0), static_cast<ssize_t>(request.size()));
    std::string response;
    char buffer[4096];
    for (ssize_t n; (n = ::recv(fd, buffer, sizeof(buffer), 0)) > 0;) response.append(buffer, n);
    ::close(fd);
    return response;
  }

  fs::path web_root_;
  LiveState state_{two_array_layout()};
  std::unique_ptr<HttpServer> server_;
};

TEST_F(HttpServerTest, UrlNamesTheBoundPort) {
  EXPECT_EQ(server_->url(), "http://127.0.0.1:" + std::to_string(server_->port()) + "/");
}

TEST_F(HttpServerTest, SiteEndpoint) {
  const json site = get_json("/api/site", 200);
  ASSERT_EQ(site["arrays"].size(), 2u);
  EXPECT_EQ(site["arrays"][0]["id"], "A1");
  EXPECT_TRUE(site["arrays"][0]["position_m"].is_array());
  EXPECT_TRUE(site["arrays"][0]["yaw_deg"].is_number());
  EXPECT_EQ(site["arrays"][0]["mics_m"].size(), 4u);
  EXPECT_EQ(site["zones"][0]["name"], "pad");
}

TEST_F(HttpServerTest, TracksEndpoint) {
  const json doc = get_json("/api/tracks", 200);
  ASSERT_EQ(doc["tracks"].size(), 1u);
  const json& t = doc["tracks"][0];
  for (const char* key : {"t", "id", "position_m", "velocity_mps", "acceleration_mps2",
                          "position_std_m", "status", "covariance_xy_m2", "contributing_arrays",
                          "speed_mps", "ground_speed_mps", "heading_deg", "last_update_s"}) {
    EXPECT_TRUE(t.contains(key)) << key;
  }
  EXPECT_EQ(t["id"], 3);
  EXPECT_NEAR(t["heading_deg"].get<double>(), 0.0, 1e-9);  // flying north
}

TEST_F(HttpServerTest, HistoryEndpointAndItsParameters) {
  state_.publish_tracks(12.1, {make_track(3, 12.1, {20, 20.5, 35}, {0, 5, 0})});
  EXPECT_EQ(get_json("/api/tracks/history", 200)["tracks"][0]["points"].size(), 2u);
  EXPECT_EQ(get_json("/api/tracks/history?since=12.05", 200)["tracks"][0]["points"].size(), 1u);
  EXPECT_EQ(get_json("/api/tracks/history?since=-1e3", 200)["tracks"][0]["points"].size(), 2u);
  for (const char* bad : {"/api/tracks/history?since=abc", "/api/tracks/history?since=",
                          "/api/tracks/history?since=nan", "/api/tracks/history?since=1e999",
                          "/api/tracks/history?since=12x", "/api/tracks/history?until=3",
                          "/api/alerts?since=yesterday", "/api/site?verbose=1"}) {
    const json error = get_json(bad, 400);
    EXPECT_TRUE(error["error"].is_string()) << bad;
  }
  EXPECT_NE(get_json("/api/tracks/history?until=3", 400)["error"].get<std::string>().find("until"),
            std::string::npos);
}

TEST_F(HttpServerTest, NodesAndAlertsEndpoints) {
  const json nodes = get_json("/api/nodes", 200);
  ASSERT_EQ(nodes["nodes"].size(), 2u);
  EXPECT_EQ(nodes["nodes"][0]["state"], "alive");
  EXPECT_EQ(nodes["nodes"][1]["state"], "stale");
  const json alerts = get_json("/api/alerts", 200);
  ASSERT_EQ(alerts["alerts"].size(), 1u);
  EXPECT_EQ(alerts["alerts"][0]["zone"], "pad");
  EXPECT_EQ(get_json("/api/alerts?since=12", 200)["alerts"].size(), 0u);
}

TEST_F(HttpServerTest, UnknownPathsAndMethodsAreJsonErrors) {
  EXPECT_TRUE(get_json("/api/nope", 404)["error"].is_string());
  EXPECT_TRUE(get_json("/api", 404)["error"].is_string());
  EXPECT_TRUE(get_json("/api/tracks/", 404)["error"].is_string());
  EXPECT_TRUE(get_json("/missing.html", 404)["error"].is_string());
  auto c = client();
  auto res = c.Post("/api/tracks", "{}", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 405);
  EXPECT_TRUE(json::parse(res->body)["error"].is_string());
}

// docs/http_api.md: a method other than GET (and HEAD) is a 405, also those httplib has no
// routes for (it answered OPTIONS with 404 and TRACE, CONNECT with 400), and a POST without
// Content-Length (which has no body; httplib waited for one until its read timeout, then 400).
TEST_F(HttpServerTest, MethodsOtherThanGetAre405) {
  auto c = client();
  auto res = c.Options("/api/tracks");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 405);
  EXPECT_EQ(res->get_header_value("Allow"), "GET, HEAD");
  EXPECT_TRUE(json::parse(res->body)["error"].is_string());
  for (const std::string& head :
       {std::string("TRACE /api/tracks HTTP/1.1\r\nHost: x\r\n"),
        std::string("CONNECT example.com:443 HTTP/1.1\r\nHost: example.com:443\r\n"),
        std::string("POST /api/tracks HTTP/1.1\r\nHost: x\r\n")}) {
    const auto start = std::chrono::steady_clock::now();
    const std::string response = raw_request(head + "Connection: close\r\n\r\n");
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1)) << head;
    ASSERT_GE(response.size(), 12u) << head;
    EXPECT_EQ(response.substr(9, 3), "405") << head << response;
    EXPECT_NE(response.find("Allow: GET, HEAD"), std::string::npos) << response;
    EXPECT_NE(response.find("\"error\""), std::string::npos) << response;
  }
}

// A number query parameter is a plain decimal number: strtod's hex, infinities, NaN and
// out-of-range values are a 400 naming the parameter.
TEST_F(HttpServerTest, NumberParametersArePlainDecimals) {
  for (const char* bad : {"0x10", "inf", "-inf", "nan", "1e999", "5abc", "%205", "+5", "1,5"}) {
    for (const std::string endpoint : {"/api/tracks/history", "/api/alerts"}) {
      const std::string path = endpoint + "?since=" + bad;
      const json error = get_json(path, 400);
      EXPECT_NE(error["error"].get<std::string>().find("'since'"), std::string::npos) << path;
    }
  }
  state_.publish_tracks(12.7, {make_track(3, 12.7, {20, 23, 35}, {0, 5, 0})});
  EXPECT_EQ(get_json("/api/tracks/history?since=12.5", 200)["tracks"][0]["points"].size(), 1u);
  EXPECT_EQ(get_json("/api/tracks/history?since=-1e3", 200)["tracks"][0]["points"].size(), 2u);
  EXPECT_EQ(get_json("/api/alerts?since=11.5", 200)["alerts"].size(), 1u);
  EXPECT_EQ(get_json("/api/alerts?since=12.5", 200)["alerts"].size(), 0u);
}

TEST_F(HttpServerTest, ServesStaticFilesWithTypes) {
  auto c = client();
  auto res = c.Get("/");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->body, "<!doctype html><title>dronetrack</title>");
  EXPECT_EQ(res->get_header_value("Content-Type"), "text/html; charset=utf-8");
  res = c.Get("/app.js");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  res = c.Get("/sub/style.css");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->body, "body{}");
}

TEST_F(HttpServerTest, RefusesTraversalHiddenFilesAndEscapingSymlinks) {
  const std::string outside = web_root_.filename().string() + "_outside.txt";
  for (const std::string& path : std::vector<std::string>{
           "/../" + outside, "/sub/../../" + outside, "/%2e%2e/" + outside, "/.secret", "/link.txt",
           "/sub/", "/sub", "//etc/passwd", "/..%2f" + outside, "/sub\\..\\app.js"}) {
    const std::string response = raw_request("GET " + path +
                                             " HTTP/1.1\r\nHost: x\r\n"
                                             "Connection: close\r\n\r\n");
    ASSERT_GE(response.size(), 12u) << path;
    const int status = std::stoi(response.substr(9, 3));
    EXPECT_GE(status, 400) << path;
    EXPECT_LT(status, 500) << path;
    EXPECT_EQ(response.find("OUTSIDE-CONTENT"), std::string::npos) << path;
    EXPECT_EQ(response.find("HIDDEN-CONTENT"), std::string::npos) << path;
    EXPECT_NE(response.find("\"error\""), std::string::npos) << path << "\n" << response;
  }
}

TEST_F(HttpServerTest, SecondServerOnTheSamePortFailsWithOneLine) {
  HttpOptions options;
  options.bind = "127.0.0.1:" + std::to_string(server_->port());
  HttpServer second(state_, options);
  try {
    second.start();
    FAIL() << "bound twice";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(options.bind), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

TEST(HttpServerBind, MalformedAddressesAreRejected) {
  LiveState state(two_array_layout());
  for (const char* bind : {"127.0.0.1", "127.0.0.1:", ":8080", "127.0.0.1:http", "127.0.0.1:70000",
                           "127.0.0.1:-1", "no.such.host.invalid:0"}) {
    HttpOptions options;
    options.bind = bind;
    HttpServer server(state, options);
    EXPECT_THROW(server.start(), std::runtime_error) << bind;
  }
}

TEST_F(HttpServerTest, StreamDeliversEveryKindOfEvent) {
  std::vector<test::SseEvent> events;
  std::mutex mutex;
  std::atomic<bool> done{false};
  std::thread reader([&] {
    auto c = client();
    test::SseParser parser;
    c.Get("/api/stream", [&](const char* data, std::size_t size) {
      std::lock_guard lock(mutex);
      parser.feed(data, size, events);
      return !done.load();
    });
  });
  const auto has = [&](const std::string& name, const std::string& needle) {
    std::lock_guard lock(mutex);
    for (const auto& e : events) {
      if (e.name == name && e.data.find(needle) != std::string::npos) return true;
    }
    return false;
  };
  const auto wait_for = [&](const std::string& name, const std::string& needle) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (!has(name, needle) && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return has(name, needle);
  };
  // The snapshot first, then what is published after connecting.
  EXPECT_TRUE(wait_for("tracks", "\"id\":3"));
  EXPECT_TRUE(wait_for("nodes", "\"array\":\"A2\""));
  state_.publish_tracks(12.1, {make_track(9, 12.1, {1, 2, 3}, {0, 0, 0})});
  doa::DoaMeasurement d;
  d.array_id = "A2";
  d.time_s = 12.1;
  state_.publish_doa(d);
  fusion::ZoneEvent e;
  e.zone = "pad";
  e.track_id = 9;
  state_.publish_alert(e);
  doa::NodeStatus s;
  s.array_id = "A2";
  s.time_s = 12.1;
  s.level_dbfs = -12.25;
  state_.publish_node(s);
  EXPECT_TRUE(wait_for("tracks", "\"id\":9"));
  EXPECT_TRUE(wait_for("doa", "\"array\":\"A2\""));
  EXPECT_TRUE(wait_for("alert", "\"track_id\":9"));
  EXPECT_TRUE(wait_for("nodes", "-12.25"));
  {
    std::lock_guard lock(mutex);
    for (const auto& event : events) EXPECT_TRUE(json::accept(event.data)) << event.data;
  }
  done = true;
  state_.publish_tracks(12.2, {});  // wakes the reader so it can stop
  reader.join();
}

TEST_F(HttpServerTest, StopEndsOpenStreamsPromptly) {
  std::thread reader([&] {
    auto c = client();
    c.Get("/api/stream", [&](const char*, std::size_t) { return true; });
  });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (state_.subscriber_count() == 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(state_.subscriber_count(), 1u);
  const auto start = std::chrono::steady_clock::now();
  server_->stop();
  reader.join();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(3));
  EXPECT_EQ(state_.subscriber_count(), 0u);
}

}  // namespace
}  // namespace dronetrack::http_api::http_server_test
