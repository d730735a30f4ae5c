#include "http_api/http_server.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <utility>

#include <sys/socket.h>
#include <nlohmann/json.hpp>

#include "http_api/authenticator.hpp"
#include "http_api/bind_address.hpp"
#include "http_api/client_address.hpp"
#include "http_api/client_budget.hpp"
#include "http_api/guarded_server.hpp"
#include "http_api/metrics_text.hpp"
#include "http_api/tls_context.hpp"

namespace dronetrack::http_api {
namespace {

void send_json(httplib::Response& res, int status, const std::string& body) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(body, "application/json");
}

void send_error(httplib::Response& res, int status, const std::string& message) {
  send_json(res, status,
            nlohmann::json{{"error", message}}.dump(-1, ' ', false,
                                                    nlohmann::json::error_handler_t::replace));
}

// Rejects query parameters the endpoint does not know, so a typo is a 400, not a silent default.
bool check_params(const httplib::Request& req, httplib::Response& res,
                  std::initializer_list<const char*> allowed) {
  for (const auto& [name, value] : req.params) {
    bool known = false;
    for (const char* a : allowed) known = known || name == a;
    if (!known) {
      send_error(res, 400, "unknown query parameter '" + name + "'");
      return false;
    }
  }
  return true;
}

// Optional number parameter; absent gives `fallback`. Only a plain decimal number is accepted
// ("12.5", "-3", "1e3"): strtod would also take "0x10", "inf", "nan" and leading spaces, which
// no client means as a stream time.
bool number_param(const httplib::Request& req, httplib::Response& res, const char* name,
                  double fallback, double& out) {
  out = fallback;
  if (!req.has_param(name)) return true;
  const std::string text = req.get_param_value(name);
  double value = 0.0;
  const char* const end = text.data() + text.size();
  const auto [stop, error] = std::from_chars(text.data(), end, value, std::chars_format::general);
  if (text.empty() || error != std::errc() || stop != end || !std::isfinite(value)) {
    send_error(res, 400,
               std::string("query parameter '") + name + "' must be a finite decimal number");
    return false;
  }
  out = value;
  return true;
}

const char* content_type_for(const std::filesystem::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json") return "application/json";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".png") return "image/png";
  if (ext == ".ico") return "image/x-icon";
  return "application/octet-stream";
}

// Maps a URL path to a file under `root`, or nothing. Only plain names: no "..", no hidden
// files, no backslashes; and the resolved file must still lie under the root (symlinks).
std::optional<std::filesystem::path> resolve_static(const std::filesystem::path& root,
                                                    const std::string& url_path) {
  std::string rel = url_path;
  if (rel.empty() || rel.front() != '/') return std::nullopt;
  rel.erase(0, 1);
  if (rel.empty()) rel = "index.html";
  for (char c : rel) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-' || c == '/';
    if (!ok) return std::nullopt;
  }
  std::size_t begin = 0;
  while (begin <= rel.size()) {
    const std::size_t end = std::min(rel.find('/', begin), rel.size());
    if (end == begin || rel[begin] == '.') return std::nullopt;  // empty, hidden or ".."
    begin = end + 1;
  }
  if (rel.back() == '/') return std::nullopt;
  std::error_code error;
  const auto canonical_root = std::filesystem::canonical(root, error);
  if (error) return std::nullopt;
  const auto file = std::filesystem::weakly_canonical(canonical_root / rel, error);
  if (error) return std::nullopt;
  const auto [root_end, file_it] =
      std::mismatch(canonical_root.begin(), canonical_root.end(), file.begin(), file.end());
  if (root_end != canonical_root.end()) return std::nullopt;
  if (!std::filesystem::is_regular_file(file, error)) return std::nullopt;
  return file;
}

bool read_file(const std::filesystem::path& file, std::string& out) {
  std::error_code error;
  const auto size = std::filesystem::file_size(file, error);
  if (error) return false;
  out.resize(size);
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (f == nullptr) return false;
  const std::size_t got = std::fread(out.data(), 1, out.size(), f);
  std::fclose(f);
  return got == out.size();
}

constexpr int kListenBacklog = 256;
constexpr int kStreamPollMs = 40;
// Workers beyond the stream clients: room for this many clients each holding its full share of
// slow connections (heads trickling in until their deadline) ...
constexpr int kSlowClientsAbsorbed = 4;
// ... and still this many for the API and the page.
constexpr int kApiWorkers = 16;

void check_limits(const HttpOptions& options) {
  const ConnectionLimits& limits = options.limits;
  const auto fail = [](const char* what) {
    throw std::runtime_error(std::string("HTTP limits: ") + what);
  };
  if (options.max_stream_clients < 0) fail("max_stream_clients must not be negative");
  if (limits.head_timeout.count() <= 0) fail("head_timeout must be positive");
  if (limits.keep_alive_timeout.count() < 0) fail("keep_alive_timeout must not be negative");
  if (limits.max_requests_per_connection < 1) fail("max_requests_per_connection must be >= 1");
  if (limits.write_timeout.count() <= 0) fail("write_timeout must be positive");
  if (limits.max_connections_per_client < 1) fail("max_connections_per_client must be >= 1");
  if (limits.max_request_bytes < 1024) fail("max_request_bytes must be at least 1024");
  if (limits.max_streams_per_client < 1) fail("max_streams_per_client must be >= 1");
  if (!(limits.request_burst_per_client >= 1.0)) fail("request_burst_per_client must be >= 1");
  if (!(limits.requests_per_second_per_client > 0.0)) {
    fail("requests_per_second_per_client must be positive");
  }
  if (limits.max_failed_logins_per_client < 1) fail("max_failed_logins_per_client must be >= 1");
}

std::string retry_after_header(double seconds) {
  return std::to_string(std::max(1, static_cast<int>(std::ceil(seconds))));
}
}  // namespace

// Anyone who can reach a non-loopback address can read the site's tracks and watch its
// defences: such an address is served only over TLS and to named users.
std::string exposure_problem(const HttpOptions& options) {
  if (options.tls_certificate.empty() != options.tls_private_key.empty()) {
    return "HTTP: TLS needs both a certificate (http.tls_certificate) and its private key "
           "(http.tls_private_key)";
  }
  const std::string host = parse_bind_address(options.bind).first;
  if (is_loopback_host(host)) return {};
  std::string missing;
  if (options.tls_certificate.empty()) missing = "TLS (http.tls_certificate, http.tls_private_key)";
  if (options.users_file.empty()) {
    missing += std::string(missing.empty() ? "" : " and ") + "users (http.users_file)";
  }
  if (missing.empty()) return {};
  return "HTTP: refusing to serve on " + options.bind + " (beyond loopback) without " + missing +
         "; see docs/http_api.md, \"Access\"";
}

HttpServer::HttpServer(LiveState& state, HttpOptions options)
    : state_(&state), options_(std::move(options)) {}

HttpServer::HttpServer(HttpOptions options) : state_(nullptr), options_(std::move(options)) {}

HttpServer::~HttpServer() { stop(); }

std::string HttpServer::url() const {
  const bool v6 = host_.find(':') != std::string::npos;
  return std::string(tls_ ? "https://" : "http://") + (v6 ? "[" + host_ + "]" : host_) + ":" +
         std::to_string(port_) + "/";
}

void HttpServer::start() {
  if (server_) throw std::runtime_error("HTTP server already started");
  auto [host, port] = parse_bind_address(options_.bind);
  host_ = host;
  check_limits(options_);
  if (const std::string problem = exposure_problem(options_); !problem.empty()) {
    throw std::runtime_error(problem);
  }
  if (!options_.tls_certificate.empty()) {
    tls_ = std::make_shared<const TlsContext>(options_.tls_certificate, options_.tls_private_key);
  }
  if (!options_.users_file.empty()) {
    authenticator_ = std::make_unique<Authenticator>(options_.users_file);
  }
  budget_ = std::make_unique<ClientBudget>(options_.limits);
  server_ = std::make_unique<GuardedServer>(options_.limits, tls_);
  // Each connection holds a worker for as long as it is open: an SSE client for as long as it
  // stays connected, a slow client until its head deadline. Size the pool so the maximum number
  // of streams and a few slow clients at their per-address limit still leave the API workers.
  const int threads = options_.max_stream_clients +
                      kSlowClientsAbsorbed * options_.limits.max_connections_per_client +
                      kApiWorkers;
  server_->new_task_queue = [threads] {
    return new httplib::ThreadPool(static_cast<std::size_t>(threads));
  };
  // httplib's default adds SO_REUSEPORT, which would let a second server silently share the
  // port. A modest send buffer (inherited by accepted sockets) bounds what a stuck client can
  // absorb before its writes block and it is cut off (after limits.write_timeout).
  server_->set_socket_options([this](socket_t sock) {
    listen_socket_ = static_cast<int>(sock);
    const int yes = 1;
    const int send_buffer_bytes = 128 * 1024;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
    ::setsockopt(sock, SOL_SOCKET, SO_SNDBUF, &send_buffer_bytes, sizeof(send_buffer_bytes));
  });
  install_routes();

  errno = 0;
  if (port == 0) {
    port_ = server_->bind_to_any_port(host_);
  } else {
    port_ = server_->bind_to_port(host_, port) ? port : -1;
  }
  if (port_ <= 0) {
    const int error = errno;
    server_.reset();
    throw std::runtime_error("cannot listen on " + options_.bind +
                             (error != 0 ? std::string(": ") + std::strerror(error) : ""));
  }
  // httplib listens with a backlog of 5: a burst of clients (a control room opening the page,
  // the load test's 50 streams) would see dropped SYNs and second-long connect delays. Linux
  // lets listen() be called again on a listening socket to raise it.
  if (listen_socket_ >= 0) ::listen(listen_socket_, kListenBacklog);
  stopping_ = false;
  auto listen_ended = std::make_shared<std::atomic<bool>>(false);
  thread_ = std::thread([this, listen_ended] {
    server_->listen_after_bind();
    *listen_ended = true;
  });
  // httplib's stop() is a no-op until the listen loop runs; wait for it so stop() always works.
  while (!server_->is_running() && !*listen_ended) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

void HttpServer::stop() {
  if (!server_) return;
  stopping_ = true;  // streams end at their next poll (40 ms)
  server_->stop_and_disconnect();
  if (thread_.joinable()) thread_.join();
  server_.reset();
}

bool HttpServer::serve_connected(int sock) {
  if (!server_) throw std::runtime_error("HTTP server not started");
  return server_->serve_connected(sock);
}

void HttpServer::install_routes() {
  httplib::Server& svr = *server_;

  svr.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr error) {
        std::string message = "internal error";
        try {
          if (error) std::rethrow_exception(error);
        } catch (const std::exception& e) {
          message = std::string("internal error: ") + e.what();
        } catch (...) {
        }
        send_error(res, 500, message);
      });
  // Whatever 4xx/5xx httplib produces on its own (bad request line, unmatched method) still
  // carries a JSON error body.
  svr.set_error_handler(
      httplib::Server::HandlerWithResponse([](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
        send_error(res, res.status,
                   "HTTP " + std::to_string(res.status) + " for " + req.method + " " + req.path);
        return httplib::Server::HandlerResponse::Handled;
      }));

  if (options_.metrics) {
    svr.Get("/metrics", [this](const httplib::Request& req, httplib::Response& res) {
      if (!check_params(req, res, {})) return;
      res.set_header("Cache-Control", "no-store");
      res.set_content(options_.metrics(), kMetricsContentType);
    });
  }
  if (state_ != nullptr) install_api_routes();
  svr.Get(R"(/api(/.*)?)", [](const httplib::Request& req, httplib::Response& res) {
    send_error(res, 404, "no such endpoint: " + req.path);
  });
  svr.Get(R"(/.*)",
          [this](const httplib::Request& req, httplib::Response& res) { serve_static(req, res); });
  // Everything is read-only: any other method is a 405 naming what is allowed.
  const auto method_not_allowed = [](const httplib::Request& req, httplib::Response& res) {
    res.set_header("Allow", "GET, HEAD");
    send_error(res, 405, "method " + req.method + " not allowed on " + req.path);
  };
  svr.Post(R"(/.*)", method_not_allowed);
  svr.Put(R"(/.*)", method_not_allowed);
  svr.Delete(R"(/.*)", method_not_allowed);
  svr.Patch(R"(/.*)", method_not_allowed);
  svr.Options(R"(/.*)", method_not_allowed);
  // Before routing: the client's request budget, its credentials, then TRACE and CONNECT,
  // which httplib parses but has no routes for (it answers 400). None carries a body httplib
  // would read.
  svr.set_pre_routing_handler(
      [this, method_not_allowed](const httplib::Request& req, httplib::Response& res) {
        if (!admit(req, res)) return httplib::Server::HandlerResponse::Handled;
        if (req.method != "TRACE" && req.method != "CONNECT") {
          return httplib::Server::HandlerResponse::Unhandled;
        }
        method_not_allowed(req, res);
        return httplib::Server::HandlerResponse::Handled;
      });
}

void HttpServer::install_api_routes() {
  httplib::Server& svr = *server_;
  svr.Get("/api/site", [this](const httplib::Request& req, httplib::Response& res) {
    if (!check_params(req, res, {})) return;
    send_json(res, 200, state_->site_json());
  });
  svr.Get("/api/tracks", [this](const httplib::Request& req, httplib::Response& res) {
    if (!check_params(req, res, {})) return;
    send_json(res, 200, state_->tracks_json());
  });
  svr.Get("/api/tracks/history", [this](const httplib::Request& req, httplib::Response& res) {
    double since = 0.0;
    if (!check_params(req, res, {"since"}) ||
        !number_param(req, res, "since", -std::numeric_limits<double>::max(), since)) {
      return;
    }
    send_json(res, 200, state_->history_json(since));
  });
  svr.Get("/api/nodes", [this](const httplib::Request& req, httplib::Response& res) {
    if (!check_params(req, res, {})) return;
    send_json(res, 200, state_->nodes_json());
  });
  svr.Get("/api/alerts", [this](const httplib::Request& req, httplib::Response& res) {
    double since = 0.0;
    if (!check_params(req, res, {"since"}) ||
        !number_param(req, res, "since", -std::numeric_limits<double>::max(), since)) {
      return;
    }
    send_json(res, 200, state_->alerts_json(since));
  });
  svr.Get("/api/stream", [this](const httplib::Request& req, httplib::Response& res) {
    if (!check_params(req, res, {})) return;
    const std::string client = client_address_key(req.remote_addr);
    if (!budget_->open_stream(client)) {
      send_error(res, 429, "too many streams from this address");
      return;
    }
    if (stream_clients_.fetch_add(1) >= options_.max_stream_clients) {
      --stream_clients_;
      budget_->close_stream(client);
      send_error(res, 503, "too many stream clients");
      return;
    }
    auto queue = state_->subscribe();
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Accel-Buffering", "no");
    const auto heartbeat = std::chrono::milliseconds(std::max(50, options_.stream_heartbeat_ms));
    auto next_nodes = std::chrono::steady_clock::now() + heartbeat;
    res.set_chunked_content_provider(
        "text/event-stream",
        [this, queue, heartbeat, next_nodes,
         batch = std::vector<std::shared_ptr<const std::string>>()](
            std::size_t, httplib::DataSink& sink) mutable {
          if (stopping_) return false;
          batch.clear();
          // Polling every 40 ms bounds the added latency and keeps >= 10 Hz delivery.
          if (!queue->pop_all(batch, kStreamPollMs)) return false;  // dropped or closed
          std::string out;
          for (const auto& event : batch) out += *event;
          const auto now = std::chrono::steady_clock::now();
          if (now >= next_nodes) {
            // Stale flags change with stream time alone; resend node health regularly.
            out += sse_event("nodes", state_->nodes_json());
            next_nodes = now + heartbeat;
          }
          return out.empty() || sink.write(out.data(), out.size());
        },
        [this, queue, client](bool) {
          state_->unsubscribe(queue);
          --stream_clients_;
          budget_->close_stream(client);
        });
  });
}

void HttpServer::serve_static(const httplib::Request& req, httplib::Response& res) const {
  if (options_.web_root.empty()) {
    send_error(res, 404, "no web root configured");
    return;
  }
  const auto file = resolve_static(options_.web_root, req.path);
  if (!file) {
    send_error(res, 404, "not found: " + req.path);
    return;
  }
  std::string body;
  if (!read_file(*file, body)) {
    send_error(res, 500, "cannot read " + req.path);
    return;
  }
  res.set_header("Cache-Control", "no-cache");
  res.set_content(std::move(body), content_type_for(*file));
}

bool HttpServer::admit(const httplib::Request& req, httplib::Response& res) {
  const std::string client = client_address_key(req.remote_addr);
  const auto now = ClientBudget::Clock::now();
  double retry_after_s = 0.0;
  if (!budget_->take_request(client, now, retry_after_s)) {
    res.set_header("Retry-After", retry_after_header(retry_after_s));
    send_error(res, 429, "too many requests from this address");
    return false;
  }
  if (!authenticator_) return true;
  if (budget_->logins_blocked(client, now, retry_after_s)) {
    res.set_header("Retry-After", retry_after_header(retry_after_s));
    send_error(res, 429, "too many failed logins from this address");
    return false;
  }
  std::string user;
  const auto result = authenticator_->check(req.get_header_value("Authorization"), user);
  if (result == Authenticator::Result::accepted) return true;
  if (result == Authenticator::Result::rejected) budget_->login_failed(client, now);
  res.set_header("WWW-Authenticate", "Basic realm=\"dronetrack\", charset=\"UTF-8\"");
  send_error(res, 401,
             result == Authenticator::Result::missing ? "credentials required"
                                                      : "wrong user name or password");
  return false;
}

}  // namespace dronetrack::http_api
