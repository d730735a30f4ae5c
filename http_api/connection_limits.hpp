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
};

}  // namespace dronetrack::http_api
