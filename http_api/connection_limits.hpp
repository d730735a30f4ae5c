#pragma once
// What one HTTP client may hold of the server, and for how long (docs/http_api.md, "Limits").
// httplib gives each connection a worker thread; these bounds keep slow or hostile clients from
// holding the workers the operator page needs, and let the server stop at once.
#include <chrono>
#include <cstddef>

namespace dronetrack::http_api {

struct ConnectionLimits {
  // A request's head (request line + headers, and a body, which this API never needs) must
  // arrive within this of the connection opening or, on a kept-alive connection, of the
  // request's first byte, however slowly it trickles. A browser sends its head in one packet;
  // 5 s is generous for a slow link yet bounds how long a trickling client holds a worker.
  std::chrono::milliseconds head_timeout{5000};
  // An idle kept-alive connection is closed after this: it holds a worker while it waits.
  std::chrono::seconds keep_alive_timeout{2};
  // Requests served on one connection before it is closed (httplib's default of 5 makes a
  // polling page reconnect all the time).
  std::size_t max_requests_per_connection = 100;
  // A write fails once the client has taken nothing for this long (a stream client that stopped
  // reading); its event queue has long since been dropped by then.
  std::chrono::milliseconds write_timeout{2000};
  // Connections one client address may hold at once (IPv6: per /64, which one host usually
  // owns); more are answered 503 and closed at once. A browser opens at most 6 per host; 8
  // leaves room for a curl beside it. Operators sharing one NAT address need more.
  int max_connections_per_client = 8;
  // Bytes of one request (head + body) before it is refused with 413: the API takes no bodies,
  // and httplib buffers a header line whole, so an endless line would otherwise grow unbounded.
  std::size_t max_request_bytes = 64 * 1024;

  // Per client address (client_address.hpp), across its connections:
  // Event streams one client may hold open at once: an operator's page holds one; a few tabs or
  // a monitoring script beside it fit. Further /api/stream requests get 429.
  int max_streams_per_client = 4;
  // Requests one client may make: a burst of this many (a page load is ~10), then this many per
  // second; beyond that 429 with Retry-After. Keeps one client from taking every worker's time.
  double request_burst_per_client = 120.0;
  double requests_per_second_per_client = 20.0;
  // Failed logins one client may make within login_failure_window before its requests get 429
  // for the rest of that window: bounds password guessing (and the ~0.2 s of PBKDF2 per guess).
  int max_failed_logins_per_client = 10;
  std::chrono::seconds login_failure_window{60};
};

}  // namespace dronetrack::http_api
