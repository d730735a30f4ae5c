// HttpServer against slow and hostile clients, over real loopback sockets: heads trickled a
// line at a time (slowloris), more connections from one address than it may hold, idle
// keep-alive connections, oversized heads, and a stop with all of them connected. Only the
// public HttpServer API and its default limits are used.
#include "http_api/http_server.hpp"
#include "tests/http_api/raw_client.hpp"
#include "tests/http_api/test_support.hpp"

#include <gtest/gtest.h>
// After our headers: <httplib.h> pulls in <resolv.h>, whose `_res` macro breaks Eigen.
#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

namespace dronetrack::http_api::hostile_clients_test {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;
using test::RawClient;

// The documented defaults (docs/http_api.md, "Limits") the assertions below rely on.
constexpr auto kHeadTimeout = std::chrono::seconds(5);
constexpr auto kKeepAliveTimeout = std::chrono::seconds(2);
constexpr int kPerClientLimit = 8;
// The slow clients come from another loopback address than the honest one, so the per-address
// limit applies to them and not to it.
constexpr const char* kSlowSource = "127.0.0.2";

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// How many complete responses (head + Content-Length body) `bytes` holds.
int complete_responses(const std::string& bytes) {
  int count = 0;
  std::size_t at = 0;
  for (;;) {
    const std::size_t head_end = bytes.find("\r\n\r\n", at);
    if (head_end == std::string::npos) return count;
    const std::string head = bytes.substr(at, head_end - at);
    const std::size_t field = head.find("Content-Length: ");
    const std::size_t length = field == std::string::npos ? 0 : std::stoul(head.substr(field + 16));
    if (bytes.size() < head_end + 4 + length) return count;
    at = head_end + 4 + length;
    ++count;
  }
}

// Connections that send a request line and then one header line every 1-2 s (each its own
// pace), never finishing the head, on a thread of their own for at most `for_at_most`.
class Slowloris {
 public:
  Slowloris(int port, int connections, Clock::duration for_at_most) {
    for (int i = 0; i < connections; ++i) {
      clients_.push_back(std::make_unique<RawClient>(port, kSlowSource));
      clients_.back()->send("GET /api/tracks HTTP/1.1\r\nHost: dronetrack\r\n");
    }
    thread_ = std::thread([this, for_at_most] { run(for_at_most); });
  }
  ~Slowloris() { finish(); }
  // Stops trickling; the connections stay open until destroyed.
  void finish() {
    done_ = true;
    if (thread_.joinable()) thread_.join();
  }
  const std::vector<std::unique_ptr<RawClient>>& clients() const { return clients_; }
  int connected() const {
    return static_cast<int>(std::count_if(clients_.begin(), clients_.end(),
                                          [](const auto& c) { return c->connected(); }));
  }
  int open() const { return open_; }

 private:
  void run(Clock::duration for_at_most) {
    const auto start = Clock::now();
    std::vector<Clock::time_point> next(clients_.size());
    for (std::size_t i = 0; i < clients_.size(); ++i) {
      next[i] = start + milliseconds(1000 + 100 * static_cast<int>(i % 11));
    }
    int line = 0;
    while (!done_ && Clock::now() - start < for_at_most) {
      int open = 0;
      for (std::size_t i = 0; i < clients_.size(); ++i) {
        RawClient& c = *clients_[i];
        c.pump();
        if (!c.closed() && Clock::now() >= next[i]) {
          c.send("X-Slow-" + std::to_string(++line) + ": still typing\r\n");
          next[i] += milliseconds(1000 + 100 * static_cast<int>(i % 11));
        }
        open += c.closed() ? 0 : 1;
      }
      open_ = open;
      std::this_thread::sleep_for(milliseconds(20));
    }
  }

  std::vector<std::unique_ptr<RawClient>> clients_;
  std::atomic<bool> done_{false};
  std::atomic<int> open_{0};
  std::thread thread_;
};

class HttpHostileClientsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    state_.publish_tracks(12.0, {test::make_track(3, 12.0, {20, 20, 35}, {0, 5, 0})});
    HttpOptions options;
    options.bind = "127.0.0.1:0";
    server_ = std::make_unique<HttpServer>(state_, options);
    server_->start();
    ASSERT_GT(server_->port(), 0);
  }
  int port() const { return server_->port(); }

  LiveState state_{test::two_array_layout()};
  std::unique_ptr<HttpServer> server_;
};

// The reported attack: a hundred connections trickling their heads. The honest client is
// served at once throughout; the slow ones over the per-address limit get a 503 at once, the
// others a 408 at the head deadline; none is left open.
TEST_F(HttpHostileClientsTest, SlowHeadsDoNotStarveTheApiAndAreCutOffAtTheHeadDeadline) {
  constexpr int kSlow = 100;
  const auto start = Clock::now();
  Slowloris slow(port(), kSlow, kHeadTimeout + std::chrono::seconds(3));
  ASSERT_EQ(slow.connected(), kSlow);

  // Honest requests while the heads trickle, each on a new connection.
  double worst_s = 0.0;
  int served = 0;
  for (int i = 0; i < 4; ++i) {
    std::this_thread::sleep_until(start + milliseconds(500 + 1000 * i));
    httplib::Client honest("127.0.0.1", port());
    honest.set_connection_timeout(5, 0);
    honest.set_read_timeout(5, 0);
    const auto sent = Clock::now();
    const auto res = honest.Get("/api/tracks");
    const double latency_s = seconds_since(sent);
    worst_s = std::max(worst_s, latency_s);
    EXPECT_TRUE(res) << "honest request " << i << " failed after " << latency_s << " s";
    if (res && res->status == 200) ++served;
    EXPECT_LT(latency_s, 2.0) << "honest request " << i;
  }
  const int open_after_4s = slow.open();

  // Past the head deadline (plus scheduling slack) every slow connection has been closed.
  const auto deadline = start + kHeadTimeout + milliseconds(1500);
  while (slow.open() > 0 && Clock::now() < deadline) std::this_thread::sleep_for(milliseconds(20));
  slow.finish();

  int refused_503 = 0;
  int timed_out_408 = 0;
  int still_open = 0;
  double first_408_s = 1e9;
  double last_close_s = 0.0;
  for (const auto& c : slow.clients()) {
    if (!c->closed()) {
      ++still_open;
      continue;
    }
    const double closed_s = std::chrono::duration<double>(c->closed_at() - start).count();
    last_close_s = std::max(last_close_s, closed_s);
    if (c->status() == 503) ++refused_503;
    if (c->status() == 408) {
      ++timed_out_408;
      first_408_s = std::min(first_408_s, closed_s);
    }
  }
  std::printf(
      "slow clients: %d trickling heads from %s; honest GET /api/tracks %d/4 served, worst "
      "latency %.3f s; %d refused with 503, %d still open after 4 s, %d answered 408 (first at "
      "%.2f s), last closed at %.2f s, %d never closed\n",
      kSlow, kSlowSource, served, worst_s, refused_503, open_after_4s, timed_out_408, first_408_s,
      last_close_s, still_open);

  EXPECT_EQ(served, 4);
  EXPECT_EQ(still_open, 0);
  // Over the limit: answered at once. The connections the server took stayed (their heads were
  // still coming) until the deadline, and then learnt why they were closed.
  EXPECT_EQ(open_after_4s, kPerClientLimit);
  EXPECT_EQ(refused_503, kSlow - kPerClientLimit);
  EXPECT_EQ(timed_out_408, kPerClientLimit);
  EXPECT_GE(first_408_s, 0.9 * std::chrono::duration<double>(kHeadTimeout).count());
}

// A kept-alive connection serves pipelined requests, then is closed once idle; a head bigger
// than the request budget is a 413, and a GET announcing a body httplib would leave unread
// ends its connection instead of having that body parsed as the next request.
TEST_F(HttpHostileClientsTest, KeepAliveIsServedThenClosedWhenIdle) {
  RawClient client(port());
  ASSERT_TRUE(client.connected());
  const std::string request = "GET /api/tracks HTTP/1.1\r\nHost: dronetrack\r\n\r\n";
  ASSERT_TRUE(client.send(request + request));  // two requests in one packet
  EXPECT_TRUE(client.pump_until([&] { return complete_responses(client.received()) == 2; },
                                milliseconds(2000)))
      << client.received();
  EXPECT_FALSE(client.closed());
  ASSERT_TRUE(client.send(request));  // and one more after a pause
  EXPECT_TRUE(client.pump_until([&] { return complete_responses(client.received()) == 3; },
                                milliseconds(2000)));
  const auto idle_since = Clock::now();
  EXPECT_TRUE(client.wait_closed(kKeepAliveTimeout + milliseconds(1500)));
  const double idle_s = seconds_since(idle_since);
  std::printf("keep-alive: 3 requests served, closed after %.2f s idle\n", idle_s);
  // Not cut off at once (the server's idle clock started a moment before ours).
  EXPECT_GE(idle_s, 0.5 * std::chrono::duration<double>(kKeepAliveTimeout).count());

  RawClient big(port());
  std::string head = "GET /api/tracks HTTP/1.1\r\nHost: dronetrack\r\n";
  while (head.size() < 70 * 1024) head += "X-Padding: " + std::string(1000, 'x') + "\r\n";
  big.send(head + "\r\n");
  EXPECT_TRUE(big.wait_closed(milliseconds(2000)));
  EXPECT_EQ(big.status(), 413) << big.received().substr(0, 200);

  RawClient with_body(port());
  const std::string body = "GET /api/nope HTTP/1.1\r\nHost: dronetrack\r\n\r\n";
  with_body.send("GET /api/tracks HTTP/1.1\r\nHost: dronetrack\r\nContent-Length: " +
                 std::to_string(body.size()) + "\r\n\r\n" + body);
  EXPECT_TRUE(with_body.wait_closed(milliseconds(2000)));
  EXPECT_EQ(with_body.status(), 200);
  EXPECT_EQ(complete_responses(with_body.received()), 1) << with_body.received();
  EXPECT_NE(with_body.received().find("Connection: close"), std::string::npos);
}

// stop() (and so the destructor) returns within a second with every kind of client connected:
// heads trickling in, idle keep-alive connections and an open event stream; and each of them
// sees its connection end.
TEST_F(HttpHostileClientsTest, StopReturnsPromptlyWhateverTheClientsDo) {
  // At most 10 s of trickling: a server that waits for these clients is caught by the timing
  // assertion instead of hanging the test.
  Slowloris slow(port(), 5, std::chrono::seconds(10));
  ASSERT_EQ(slow.connected(), 5);

  std::vector<std::unique_ptr<RawClient>> idle;
  for (int i = 0; i < 3; ++i) {
    idle.push_back(std::make_unique<RawClient>(port()));
    RawClient& c = *idle.back();
    ASSERT_TRUE(c.send("GET /api/site HTTP/1.1\r\nHost: dronetrack\r\n\r\n"));
    EXPECT_TRUE(
        c.pump_until([&] { return complete_responses(c.received()) == 1; }, milliseconds(2000)));
  }
  RawClient stream(port());
  ASSERT_TRUE(stream.send("GET /api/stream HTTP/1.1\r\nHost: dronetrack\r\n\r\n"));
  EXPECT_TRUE(stream.pump_until(
      [&] { return stream.received().find("event: tracks") != std::string::npos; },
      milliseconds(2000)));
  EXPECT_EQ(state_.subscriber_count(), 1u);
  std::this_thread::sleep_for(milliseconds(300));  // the slow heads are well under way

  const auto start = Clock::now();
  server_.reset();  // stop() and the destructor
  const double stop_s = seconds_since(start);
  std::printf(
      "shutdown: 5 trickling heads, 3 idle keep-alive connections, 1 event stream -> stopped in "
      "%.1f ms\n",
      stop_s * 1e3);
  EXPECT_LT(stop_s, 1.5);
  EXPECT_EQ(state_.subscriber_count(), 0u);

  slow.finish();
  for (const auto& c : slow.clients()) EXPECT_TRUE(c->wait_closed(milliseconds(500)));
  for (const auto& c : idle) EXPECT_TRUE(c->wait_closed(milliseconds(500)));
  EXPECT_TRUE(stream.wait_closed(milliseconds(500)));
}

}  // namespace
}  // namespace dronetrack::http_api::hostile_clients_test
