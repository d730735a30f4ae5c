// Load: 50 concurrent SSE clients plus one that connects and never reads, while a publisher
// publishes tracks and DOAs at 20 Hz. The publisher keeps its rate, the good clients keep
// receiving everything, and the stuck client is cut off instead of holding anyone up.
#include "http_api/http_server.hpp"
#include "tests/http_api/test_support.hpp"

#include <gtest/gtest.h>
// After our headers: <httplib.h> pulls in <resolv.h>, whose `_res` macro breaks Eigen.
#include <httplib.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

namespace dronetrack::http_api::sse_load_test {
namespace {

using Clock = std::chrono::steady_clock;
using test::make_track;

struct GoodClient {
  std::thread thread;
  std::atomic<int> tracks_events{0};
  std::atomic<double> last_tracks_time_s{-1.0};
};

TEST(SseLoad, FiftyClientsAndAStuckOneDoNotSlowThePublisher) {
  constexpr int kClients = 50;
  constexpr int kTicks = 100;  // 5 s at 20 Hz
  constexpr double kRateHz = 20.0;
  LiveStateLimits limits;
  limits.stream_queue_events = 256;
  LiveState state(test::two_array_layout(), limits);
  HttpOptions options;
  options.bind = "127.0.0.1:0";
  options.max_stream_clients = 64;
  // Every client here comes from 127.0.0.1: lift the per-address limit above them all.
  options.limits.max_connections_per_client = kClients + 1;
  options.limits.max_streams_per_client = kClients + 1;  // every client here is 127.0.0.1
  HttpServer server(state, options);
  server.start();

  std::atomic<bool> done{false};
  std::vector<std::unique_ptr<GoodClient>> clients;
  for (int c = 0; c < kClients; ++c) {
    auto client = std::make_unique<GoodClient>();
    GoodClient* self = client.get();
    client->thread = std::thread([self, &server, &done] {
      httplib::Client http("127.0.0.1", server.port());
      http.set_read_timeout(10, 0);
      test::SseParser parser;
      std::vector<test::SseEvent> events;
      http.Get("/api/stream", [&](const char* data, std::size_t size) {
        events.clear();
        parser.feed(data, size, events);
        for (const auto& e : events) {
          if (e.name != "tracks") continue;
          ++self->tracks_events;
          // "t" is the first key of the document: {"t":1.25,...
          self->last_tracks_time_s = std::strtod(e.data.c_str() + 5, nullptr);
        }
        return !done.load();
      });
    });
    clients.push_back(std::move(client));
  }

  // The stuck client: a tiny receive buffer, a request, and then silence.
  const int stuck = ::socket(AF_INET, SOCK_STREAM, 0);
  const int small_buffer = 1024;
  ::setsockopt(stuck, SOL_SOCKET, SO_RCVBUF, &small_buffer, sizeof(small_buffer));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(server.port()));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  // EXPECT, not ASSERT, from here on: the client threads must be joined whatever happens.
  EXPECT_EQ(::connect(stuck, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  const std::string request = "GET /api/stream HTTP/1.1\r\nHost: x\r\n\r\n";
  EXPECT_EQ(::send(stuck, request.data(), request.size(), 0), static_cast<ssize_t>(request.size()));

  const auto connect_start = Clock::now();
  auto deadline = connect_start + std::chrono::seconds(10);
  while (state.subscriber_count() < kClients + 1 && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const double connect_s = std::chrono::duration<double>(Clock::now() - connect_start).count();
  // All 51 streams open within two seconds. httplib's own listen backlog of 5 (HttpServer
  // raises it) drops most of the 51 SYNs; the clients resend after 1 s, all at once, so the
  // backlog overflows again and some wait for the second resend, 3 s after the first. Under 1 s on
  // an idle machine; 1.2 s was seen with the 2 cores loaded by other builds.
  EXPECT_EQ(state.subscriber_count(), static_cast<std::size_t>(kClients + 1));
  EXPECT_LT(connect_s, 2.0);

  // A realistic picture: 8 tracks and 4 DOAs per tick (several kB per tracks event), so the
  // stuck client's socket buffers fill within the run.
  std::vector<fusion::TrackReport> tracks;
  const auto period = std::chrono::duration<double>(1.0 / kRateHz);
  const auto start = Clock::now();
  double max_publish_ms = 0.0;
  double total_publish_ms = 0.0;
  double max_late_ms = 0.0;
  for (int k = 0; k < kTicks; ++k) {
    const auto due = start + std::chrono::duration_cast<Clock::duration>(period * k);
    max_late_ms = std::max(max_late_ms,
                           std::chrono::duration<double, std::milli>(Clock::now() - due).count());
    std::this_thread::sleep_until(due);
    const double t = k / kRateHz;
    tracks.clear();
    for (int id = 1; id <= 8; ++id)
      tracks.push_back(make_track(id, t, {t, id * 5.0, 30}, {1, 0, 0}));
    const auto before = Clock::now();
    state.publish_tracks(t, tracks);
    for (int a = 0; a < 4; ++a) {
      doa::DoaMeasurement d;
      d.array_id = std::string(a % 2 == 0 ? "A1" : "A2");
      d.source_index = a / 2;
      d.time_s = t;
      state.publish_doa(d);
    }
    const double publish_ms =
        std::chrono::duration<double, std::milli>(Clock::now() - before).count();
    max_publish_ms = std::max(max_publish_ms, publish_ms);
    total_publish_ms += publish_ms;
  }
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
  const double achieved_hz = (kTicks - 1) / elapsed_s;
  const double last_t = (kTicks - 1) / kRateHz;

  // Good clients catch up with the last tick; the stuck one has been cut off by then.
  deadline = Clock::now() + std::chrono::seconds(5);
  const auto all_caught_up = [&] {
    return std::all_of(clients.begin(), clients.end(),
                       [&](const auto& c) { return c->last_tracks_time_s.load() >= last_t; });
  };
  while ((!all_caught_up() || state.subscriber_count() > kClients) && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  int min_events = kTicks * 10;
  for (const auto& c : clients) min_events = std::min(min_events, c->tracks_events.load());
  const double mean_publish_ms = total_publish_ms / kTicks;
  std::printf(
      "sse load: %d ticks at %.1f Hz target -> %.2f Hz achieved, publish mean %.3f ms max %.3f ms, "
      "max tick lateness %.1f ms; %d clients connected in %.2f s, fewest tracks events %d/%d; "
      "subscribers now %zu, dropped for a full queue %lld\n",
      kTicks, kRateHz, achieved_hz, mean_publish_ms, max_publish_ms, max_late_ms, kClients,
      connect_s, min_events, kTicks + 1, state.subscriber_count(),
      static_cast<long long>(state.dropped_clients()));

  // The rate holds over the run (ticks are scheduled on absolute deadlines, so only a publisher
  // that is held up can lose them). Single calls may wait for the CPU on a loaded 2-core
  // machine under a sanitizer (tens of ms); a publisher blocked by the stuck client would wait
  // for the 2 s write timeout, which these bounds catch.
  EXPECT_GE(achieved_hz, 0.98 * kRateHz);
  EXPECT_LT(mean_publish_ms, 10.0);
  EXPECT_LT(max_publish_ms, 250.0);
  EXPECT_LT(max_late_ms, 250.0);
  EXPECT_TRUE(all_caught_up());
  // The snapshot on connect plus every tick: nothing was lost by a good client.
  EXPECT_GE(min_events, kTicks);
  EXPECT_EQ(state.subscriber_count(), static_cast<std::size_t>(kClients));

  done = true;
  state.publish_tracks(last_t + 1.0, {});  // wakes every reader so it can stop
  for (auto& c : clients) c->thread.join();
  ::close(stuck);
  server.stop();
}

}  // namespace
}  // namespace dronetrack::http_api::sse_load_test
