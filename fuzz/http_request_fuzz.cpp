// The operator HTTP API (http_api/): raw bytes as one client connection, through the real
// server (GuardedServer's bounded stream, httplib's request parser, our routes: query
// parameters such as since=, unknown parameters, paths to the web root, methods, bodies,
// Last-Event-ID and other headers) over a socketpair, on a live state holding tracks, a node,
// an alert and DOAs. Properties: no input crashes, hangs or leaks the server.
#include <sys/socket.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <memory>

#include "fuzz/fuzz_support.hpp"
#include "http_api/http_server.hpp"
#include "http_api/live_state.hpp"
#include "tests/http_api/test_support.hpp"

namespace {

namespace http = dronetrack::http_api;

http::LiveState& state() {
  static http::LiveState live(http::test::two_array_layout());
  static const bool filled = [] {
    for (int tick = 0; tick < 20; ++tick) {
      const double t = 0.1 * tick;
      live.publish_tracks(t, {http::test::make_track(1, t, {5.0 + t, 20, 30}, {1, 0, 0}),
                              http::test::make_track(2, t, {20, 20, 40}, {0, 0, 0})});
    }
    dronetrack::doa::NodeStatus status;
    status.array_id = "A1";
    status.time_s = 1.9;
    status.sample_rate_hz = 48000.0;
    live.publish_node(status);
    dronetrack::fusion::ZoneEvent alert;
    alert.zone = "pad";
    alert.track_id = 2;
    alert.entered = true;
    alert.time_s = 1.0;
    alert.position_m = {20, 20, 40};
    live.publish_alert(alert);
    dronetrack::doa::DoaMeasurement doa;
    doa.array_id = "A1";
    doa.time_s = 1.9;
    doa.direction = {0.6, 0.8, 0.0};
    live.publish_doa(doa);
    return true;
  }();
  (void)filled;
  return live;
}

http::HttpServer& server() {
  static http::HttpServer* running = [] {
    http::HttpOptions options;
    options.bind = "127.0.0.1:0";  // bound but never connected to: inputs come by socketpair
    options.web_root = DRONETRACK_SOURCE_DIR "/web";
    options.stream_heartbeat_ms = 50;
    // A request that stops short ends at the client's end of stream, never at a deadline.
    options.limits.head_timeout = std::chrono::milliseconds(200);
    options.limits.keep_alive_timeout = std::chrono::seconds(0);
    // Never deleted: its listener thread runs until the process exits.
    auto* created = new http::HttpServer(state(), options);
    created->start();
    return created;
  }();
  return *running;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The whole request must fit the socket buffer: it is written before the server reads.
  if (size > 64 * 1024) return 0;
  http::HttpServer& served = server();
  int fds[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM, 0, fds) != 0) dronetrack::fuzz::fail("socketpair");
  const int buffer_bytes = 256 * 1024;
  ::setsockopt(fds[0], SOL_SOCKET, SO_SNDBUF, &buffer_bytes, sizeof(buffer_bytes));
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fds[0], data + done, size - done);
    if (n <= 0) dronetrack::fuzz::fail("socketpair write");
    done += static_cast<std::size_t>(n);
  }
  // The client has said everything and hung up: the server reads the request to its end, and
  // its responses fail at once (EPIPE) instead of filling a buffer nobody reads.
  ::close(fds[0]);
  served.serve_connected(fds[1]);  // closes fds[1]
  return 0;
}
