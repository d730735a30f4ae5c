#pragma once
// The operator's HTTP server: the JSON API and Server-Sent Events over a LiveState, and the
// static web page. Handlers only serialise snapshots; a slow client never slows the publisher.
#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "http_api/connection_limits.hpp"
#include "http_api/live_state.hpp"

namespace httplib {
struct Request;
struct Response;
}  // namespace httplib

namespace dronetrack::http_api {

class Authenticator;
class ClientBudget;
class GuardedServer;
class TlsContext;

struct HttpOptions {
  std::string bind = "127.0.0.1:8080";  // HOST:PORT; port 0 picks a free port (see port())
  // HTTPS: a PEM certificate chain and its private key (both or neither). Users: a users file
  // (user_file.hpp); requests then need HTTP Basic credentials. Serving beyond loopback needs
  // both (docs/http_api.md, "Access").
  std::filesystem::path tls_certificate;
  std::filesystem::path tls_private_key;
  std::filesystem::path users_file;
  std::filesystem::path web_root;  // the page (index.html, app.js, ...); empty: API only
  int max_stream_clients = 64;     // further /api/stream requests get 503
  int stream_heartbeat_ms = 1000;  // a nodes event (stale flags) at least this often
  ConnectionLimits limits;         // slow and hostile clients (connection_limits.hpp)
  // GET /metrics: the Prometheus text body (http_api/metrics_text.hpp), built per scrape on the
  // server's thread, so it must be thread-safe. Empty: no /metrics.
  std::function<std::string()> metrics;
};

// Why `options` may not be served as they stand (a TLS half given, or an address beyond
// loopback without TLS and users; docs/http_api.md "Access"), or "" if they may. start()
// refuses them with the same line.
std::string exposure_problem(const HttpOptions& options);

class HttpServer {
 public:
  HttpServer(LiveState& state, HttpOptions options);
  // Without a live state: only /metrics (a node's listener, `node --metrics-listen`), under
  // the same limits, TLS and users rules.
  explicit HttpServer(HttpOptions options);
  ~HttpServer();  // stops
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  // Binds and serves on a background thread. Throws std::runtime_error with a one-line message
  // if the address is malformed or cannot be bound, a limit is out of range, the TLS files or
  // the users file cannot be used, or the address is beyond loopback without TLS and users.
  void start();
  // Returns within about 0.1 s whatever the clients do: every open connection is shut down.
  void stop();
  // After start(): serves one connected socket on the calling thread through the same routes
  // and limits, then closes it (fuzz/http_request_fuzz.cpp feeds raw requests this way).
  bool serve_connected(int sock);
  int port() const { return port_; }
  std::string url() const;  // http://HOST:PORT/ or https://HOST:PORT/

 private:
  void install_routes();
  void install_api_routes();  // with a live state
  void serve_static(const httplib::Request& req, httplib::Response& res) const;
  // The client's request budget and credentials; false: `res` holds the refusal (429, 401).
  bool admit(const httplib::Request& req, httplib::Response& res);

  LiveState* state_;  // null: /metrics only
  HttpOptions options_;
  std::string host_;
  int port_ = 0;
  int listen_socket_ = -1;  // seen in httplib's socket-options hook, to raise the backlog
  std::shared_ptr<const TlsContext> tls_;
  std::unique_ptr<Authenticator> authenticator_;
  std::unique_ptr<ClientBudget> budget_;
  std::unique_ptr<GuardedServer> server_;
  std::thread thread_;
  std::atomic<bool> stopping_{false};
  std::atomic<int> stream_clients_{0};
};

}  // namespace dronetrack::http_api
