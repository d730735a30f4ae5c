#pragma once
// An httplib::Server whose connections cannot outlive their welcome. httplib 0.11.4 gives each
// connection a worker thread and only a per-recv() read timeout, so a client that trickles one
// header byte every few seconds holds its worker forever, a hundred of them starve everyone
// else, and stop() waits for them all. GuardedServer replaces httplib's per-connection loop
// (the private virtual process_and_close_socket) with one that bounds every connection:
// - the request head (and any body) must arrive within a deadline, however slowly it trickles;
// - an idle keep-alive connection is closed after the keep-alive timeout;
// - each client address may hold only so many connections; more get a 503 and are closed;
// - stop_and_disconnect() shuts every live socket down, so all workers return within one poll
//   slice (50 ms) whatever their clients do;
// - optionally, TLS (OpenSSL directly: httplib's SSLServer has its own per-connection loop),
//   the handshake bounded like a request head.
// Requests are still parsed, routed and answered by httplib (process_request); only the socket
// I/O underneath goes through our own Stream.
// Include after Eigen-using headers: <httplib.h> pulls in <resolv.h>, whose `_res` macro breaks
// Eigen.
#include <httplib.h>

#include <atomic>
#include <cstddef>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "http_api/connection_limits.hpp"

struct ssl_st;  // OpenSSL's SSL

namespace dronetrack::http_api {

class TlsContext;

class GuardedServer : public httplib::Server {
 public:
  // Also sets httplib's keep-alive timeout, request count and write timeout from `limits`, so
  // the Keep-Alive header a response carries says what this server does. With `tls`, every
  // connection is TLS: the handshake must complete within limits.head_timeout.
  explicit GuardedServer(const ConnectionLimits& limits,
                         std::shared_ptr<const TlsContext> tls = nullptr);

  // Stops accepting, and shuts down every open connection (slow heads, idle keep-alives,
  // streams): their workers see the socket end within one poll slice and return. The thread
  // running listen_after_bind() then returns once those workers are joined.
  void stop_and_disconnect();
  // Serves one already-connected socket on the calling thread, as if accepted, and closes it
  // (the fuzz harness feeds raw requests through a socketpair: fuzz/http_request_fuzz.cpp).
  bool serve_connected(socket_t sock) { return process_and_close_socket(sock); }

 private:
  // Called by httplib on a worker thread for each accepted socket; owns and closes it.
  bool process_and_close_socket(socket_t sock) override;

  enum class Admission { admitted, over_limit, stopping };
  Admission admit(socket_t sock, const std::string& client);
  void release(socket_t sock, const std::string& client);
  // Reads, routes and answers requests on one admitted connection until it ends (after the
  // TLS handshake, with TLS).
  bool serve(socket_t sock);
  bool serve_requests(socket_t sock, ssl_st* ssl);

  const ConnectionLimits limits_;
  const std::shared_ptr<const TlsContext> tls_;
  std::atomic<bool> stopping_{false};
  std::mutex mutex_;  // guards the two containers and, with them, stopping_ changes
  std::unordered_set<socket_t> live_sockets_;
  std::unordered_map<std::string, int> connections_per_client_;
};

}  // namespace dronetrack::http_api
