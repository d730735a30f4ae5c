#include "http_api/guarded_server.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string_view>

#include <openssl/err.h>
#include <openssl/ssl.h>

#include "http_api/client_address.hpp"
#include "http_api/tls_context.hpp"

namespace dronetrack::http_api {
namespace {

using Clock = std::chrono::steady_clock;

// Longest a waiting worker goes without looking at the stop flag. stop_and_disconnect() also
// shuts the socket down, which wakes poll() at once; the slice is the backstop.
constexpr auto kPollSlice = std::chrono::milliseconds(50);

enum class Wait { ready, timed_out, stopped, failed };

// Waits until `sock` reports `events` (or hang-up/error: the next call says which), until
// `deadline`, or until `stopping`.
Wait wait_for(socket_t sock, short events, Clock::time_point deadline,
              const std::atomic<bool>& stopping) {
  for (;;) {
    if (stopping) return Wait::stopped;
    const auto now = Clock::now();
    if (now >= deadline) return Wait::timed_out;
    const auto slice = std::min<Clock::duration>(kPollSlice, deadline - now);
    const auto slice_ms = std::chrono::ceil<std::chrono::milliseconds>(slice).count();
    pollfd entry{sock, events, 0};
    const int n = ::poll(&entry, 1, static_cast<int>(slice_ms));
    if (n > 0) return (entry.revents & POLLNVAL) != 0 ? Wait::failed : Wait::ready;
    if (n < 0 && errno != EINTR) return Wait::failed;
  }
}

bool would_block(int error) { return error == EAGAIN || error == EWOULDBLOCK || error == EINTR; }

// One complete response with a JSON error body and "Connection: close".
std::string error_response(int status, std::string_view reason, std::string_view message) {
  const std::string body = "{\"error\":\"" + std::string(message) + "\"}";
  return "HTTP/1.1 " + std::to_string(status) + " " + std::string(reason) +
         "\r\nContent-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
         "\r\nConnection: close\r\n\r\n" + body;
}

// Sent without waiting: it is only ever sent into an idle socket, whose send buffer has room.
void send_error_and_close(socket_t sock, int status, std::string_view reason,
                          std::string_view message) {
  const std::string response = error_response(status, reason, message);
  (void)::send(sock, response.data(), response.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
  ::shutdown(sock, SHUT_WR);
}

// What a non-blocking TLS call that did not complete waits for, or 0 if it failed for good.
short tls_wait_events(SSL* ssl, int result) {
  switch (SSL_get_error(ssl, result)) {
    case SSL_ERROR_WANT_READ:
      return POLLIN;
    case SSL_ERROR_WANT_WRITE:
      return POLLOUT;
    default:
      return 0;
  }
}

// The TLS handshake on a non-blocking socket, bounded like a request head: a client that opens
// a connection and never completes the handshake holds its worker no longer than one that
// trickles a head.
bool accept_tls(SSL* ssl, socket_t sock, Clock::time_point deadline,
                const std::atomic<bool>& stopping) {
  for (;;) {
    ERR_clear_error();
    const int result = SSL_accept(ssl);
    if (result == 1) return true;
    const short events = tls_wait_events(ssl, result);
    if (events == 0 || wait_for(sock, events, deadline, stopping) != Wait::ready) return false;
  }
}

struct SslFree {
  void operator()(SSL* ssl) const { SSL_free(ssl); }
};
using SslPointer = std::unique_ptr<SSL, SslFree>;

void numeric_address(const sockaddr_storage& addr, socklen_t length, std::string& ip, int& port) {
  std::array<char, NI_MAXHOST> host{};
  std::array<char, NI_MAXSERV> service{};
  if (::getnameinfo(reinterpret_cast<const sockaddr*>(&addr), length, host.data(), host.size(),
                    service.data(), service.size(), NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
    ip = host.data();
    port = std::atoi(service.data());
  }
}

// The address a connection counts against (client_address.hpp); empty if the peer is already
// gone.
std::string client_key(socket_t sock) {
  sockaddr_storage addr{};
  socklen_t length = sizeof(addr);
  if (::getpeername(sock, reinterpret_cast<sockaddr*>(&addr), &length) != 0) return {};
  std::string ip;
  int port = 0;
  numeric_address(addr, length, ip, port);
  return ip.empty() ? std::string("other") : client_address_key(ip);
}

// httplib reads (and throws away) the body of these methods before routing; of any other
// request it reads only the head.
bool httplib_reads_body(const httplib::Request& req) {
  return req.method == "POST" || req.method == "PUT" || req.method == "PATCH" ||
         req.method == "DELETE" || req.method == "PRI";
}

bool announces_body(const httplib::Request& req) {
  if (req.has_header("Transfer-Encoding")) return true;
  const std::string length = req.get_header_value("Content-Length");
  return !length.empty() && length.find_first_not_of('0') != std::string::npos;
}

// The socket under httplib's parser, for one connection. Reads are buffered (httplib reads the
// head a byte at a time) and, per request, bounded by a deadline and a byte budget; a read that
// misses either answers the request itself (408, 413) and ends the connection. A write fails
// when the client has taken nothing for the write timeout. Every wait ends at a stop. With TLS
// (`ssl` not null; the socket is then non-blocking) the same bounds apply to the records.
class GuardedStream final : public httplib::Stream {
 public:
  GuardedStream(socket_t sock, SSL* ssl, const ConnectionLimits& limits,
                const std::atomic<bool>& stopping)
      : sock_(sock), ssl_(ssl), limits_(limits), stopping_(stopping) {}

  // A request starts: all of it must be read within the head timeout from now.
  void begin_request() {
    read_deadline_ = Clock::now() + limits_.head_timeout;
    request_bytes_ = 0;
  }
  // Waits up to `idle` for the first byte of the next request; false if it does not come, the
  // client leaves or the server stops.
  bool wait_for_next_request(Clock::duration idle) {
    if (begin_ < end_ || tls_buffered()) return true;  // pipelined: already buffered
    return wait_for(sock_, POLLIN, Clock::now() + idle, stopping_) == Wait::ready;
  }
  // No further request can be read: the client closed, a read failed, or we answered it.
  bool ended() const { return ended_; }

  bool is_readable() const override {
    if (begin_ < end_ || tls_buffered()) return true;
    pollfd entry{sock_, POLLIN, 0};
    return ::poll(&entry, 1, 0) > 0;
  }
  bool is_writable() const override {
    return !answered_ &&
           wait_for(sock_, POLLOUT, Clock::now() + limits_.write_timeout, stopping_) == Wait::ready;
  }

  ssize_t read(char* ptr, size_t size) override {
    if (begin_ == end_) {
      const ssize_t got = fill();
      if (got <= 0) return got;
    }
    const std::size_t n = std::min(size, end_ - begin_);
    if (request_bytes_ + n > limits_.max_request_bytes) {
      answer(413, "Content Too Large",
             "request larger than " + std::to_string(limits_.max_request_bytes) + " bytes");
      return -1;
    }
    std::memcpy(ptr, buffer_.data() + begin_, n);
    begin_ += n;
    request_bytes_ += n;
    return static_cast<ssize_t>(n);
  }

  using httplib::Stream::write;
  ssize_t write(const char* ptr, size_t size) override {
    if (answered_) return -1;  // our own error response was the last word
    if (size == 0) return 0;
    const auto deadline = Clock::now() + limits_.write_timeout;
    short events = POLLOUT;
    for (;;) {
      if (wait_for(sock_, events, deadline, stopping_) != Wait::ready) return -1;
      if (ssl_ != nullptr) {
        ERR_clear_error();
        const int n = SSL_write(ssl_, ptr, static_cast<int>(std::min<size_t>(size, 1 << 30)));
        if (n > 0) return n;
        events = tls_wait_events(ssl_, n);
        if (events == 0) return -1;
        continue;
      }
      const ssize_t n = ::send(sock_, ptr, size, MSG_DONTWAIT | MSG_NOSIGNAL);
      if (n >= 0 || !would_block(errno)) return n;
    }
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t length = sizeof(addr);
    if (::getpeername(sock_, reinterpret_cast<sockaddr*>(&addr), &length) == 0) {
      numeric_address(addr, length, ip, port);
    }
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t length = sizeof(addr);
    if (::getsockname(sock_, reinterpret_cast<sockaddr*>(&addr), &length) == 0) {
      numeric_address(addr, length, ip, port);
    }
  }
  socket_t socket() const override { return sock_; }

 private:
  bool tls_buffered() const { return ssl_ != nullptr && SSL_pending(ssl_) > 0; }

  // One non-blocking read from the socket or the TLS session: > 0 bytes, 0 at the client's end
  // of stream, -1 on failure; `retry_events` != 0: nothing yet, wait for those and call again.
  ssize_t receive_now(short& retry_events) {
    retry_events = 0;
    if (ssl_ != nullptr) {
      ERR_clear_error();
      const int n = SSL_read(ssl_, buffer_.data(), static_cast<int>(buffer_.size()));
      if (n > 0) return n;
      if (SSL_get_error(ssl_, n) == SSL_ERROR_ZERO_RETURN) return 0;
      retry_events = tls_wait_events(ssl_, n);
      return -1;
    }
    const ssize_t n = ::recv(sock_, buffer_.data(), buffer_.size(), MSG_DONTWAIT);
    if (n < 0 && would_block(errno)) retry_events = POLLIN;
    return n;
  }

  // Refills the empty buffer: > 0 bytes, 0 at the client's end of stream, -1 on failure.
  ssize_t fill() {
    short events = tls_buffered() ? 0 : POLLIN;
    for (;;) {
      const Wait wait =
          events == 0 ? Wait::ready : wait_for(sock_, events, read_deadline_, stopping_);
      if (wait == Wait::timed_out) {
        // A connection that never sent a byte is just closed, as a browser's unused
        // preconnection expects; one that started a request learns why it ends.
        if (request_bytes_ > 0) {
          const auto seconds = std::chrono::duration<double>(limits_.head_timeout).count();
          char text[64];
          std::snprintf(text, sizeof(text), "request not received within %g s", seconds);
          answer(408, "Request Timeout", text);
        }
        ended_ = true;
        return -1;
      }
      if (wait != Wait::ready) {
        ended_ = true;
        return -1;
      }
      const ssize_t n = receive_now(events);
      if (n >= 0) {
        begin_ = 0;
        end_ = static_cast<std::size_t>(n);
        if (n == 0) ended_ = true;
        return n;
      }
      if (events == 0) {
        ended_ = true;
        return -1;
      }
    }
  }

  void answer(int status, std::string_view reason, std::string_view message) {
    if (ssl_ != nullptr) {
      // Best effort, without waiting: the connection ends after it either way.
      const std::string response = error_response(status, reason, message);
      ERR_clear_error();
      (void)SSL_write(ssl_, response.data(), static_cast<int>(response.size()));
    } else {
      send_error_and_close(sock_, status, reason, message);
    }
    answered_ = true;
    ended_ = true;
  }

  const socket_t sock_;
  SSL* const ssl_;
  const ConnectionLimits& limits_;
  const std::atomic<bool>& stopping_;
  std::array<char, 4096> buffer_{};
  std::size_t begin_ = 0;  // unread bytes are buffer_[begin_, end_)
  std::size_t end_ = 0;
  Clock::time_point read_deadline_;
  std::size_t request_bytes_ = 0;
  bool ended_ = false;
  bool answered_ = false;
};

}  // namespace

GuardedServer::GuardedServer(const ConnectionLimits& limits, std::shared_ptr<const TlsContext> tls)
    : limits_(limits), tls_(std::move(tls)) {
  set_keep_alive_timeout(limits.keep_alive_timeout.count());
  set_keep_alive_max_count(limits.max_requests_per_connection);
  set_write_timeout(limits.write_timeout);
}

void GuardedServer::stop_and_disconnect() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    for (socket_t sock : live_sockets_) ::shutdown(sock, SHUT_RDWR);
  }
  stop();  // httplib: closes the listening socket; listen_after_bind() joins the workers
}

GuardedServer::Admission GuardedServer::admit(socket_t sock, const std::string& client) {
  std::lock_guard lock(mutex_);
  if (stopping_) return Admission::stopping;
  int& count = connections_per_client_[client];
  if (count >= limits_.max_connections_per_client) return Admission::over_limit;
  ++count;
  live_sockets_.insert(sock);
  return Admission::admitted;
}

void GuardedServer::release(socket_t sock, const std::string& client) {
  std::lock_guard lock(mutex_);
  live_sockets_.erase(sock);
  if (--connections_per_client_[client] <= 0) connections_per_client_.erase(client);
}

bool GuardedServer::process_and_close_socket(socket_t sock) {
  const std::string client = client_key(sock);
  bool ok = false;
  switch (client.empty() ? Admission::stopping : admit(sock, client)) {
    case Admission::admitted:
      ok = serve(sock);
      release(sock, client);
      break;
    case Admission::over_limit:
      // Over TLS a plaintext answer would be garbage to the client: it just sees the close.
      if (!tls_) {
        send_error_and_close(sock, 503, "Service Unavailable",
                             "too many connections from this address");
      }
      break;
    case Admission::stopping:
      break;
  }
  // Read what the client has already sent (up to 64 kB, without waiting): closing a socket with
  // unread data resets the connection, which can destroy our last response (503, 408, 413)
  // before the client reads it.
  std::array<char, 4096> sink{};
  for (int i = 0; i < 16 && ::recv(sock, sink.data(), sink.size(), MSG_DONTWAIT) > 0; ++i) {
  }
  ::shutdown(sock, SHUT_RDWR);
  ::close(sock);
  return ok;
}

bool GuardedServer::serve(socket_t sock) {
  SslPointer ssl;
  if (tls_) {
    const int flags = ::fcntl(sock, F_GETFL, 0);
    if (flags < 0 || ::fcntl(sock, F_SETFL, flags | O_NONBLOCK) != 0) return false;
    ssl.reset(SSL_new(tls_->native()));
    if (!ssl || SSL_set_fd(ssl.get(), sock) != 1 ||
        !accept_tls(ssl.get(), sock, Clock::now() + limits_.head_timeout, stopping_)) {
      return false;
    }
  }
  const bool ok = serve_requests(sock, ssl.get());
  if (ssl) {
    ERR_clear_error();
    (void)SSL_shutdown(ssl.get());  // close_notify, without waiting for the client's
  }
  return ok;
}

bool GuardedServer::serve_requests(socket_t sock, SSL* ssl) {
  GuardedStream stream(sock, ssl, limits_, stopping_);
  bool ok = true;
  for (std::size_t count = 0; count < limits_.max_requests_per_connection; ++count) {
    // The first request is due from the moment the connection opens; a later one may keep the
    // client waiting up to the keep-alive timeout before its first byte.
    if (count > 0 && !stream.wait_for_next_request(limits_.keep_alive_timeout)) break;
    stream.begin_request();
    bool connection_closed = false;
    bool unread_body = false;
    const bool last = count + 1 == limits_.max_requests_per_connection;
    // Called once the head is parsed, before routing: settles how the body is framed.
    ok = process_request(stream, last, connection_closed, [&](httplib::Request& req) {
      if (!httplib_reads_body(req) && announces_body(req)) {
        // httplib would leave this body in the socket and parse it as the next request:
        // answer this one with "Connection: close" instead.
        unread_body = true;
        req.headers.erase("Connection");
        req.headers.emplace("Connection", "close");
      }
      if (!req.has_header("Content-Length") && !req.has_header("Transfer-Encoding")) {
        // Such a request has no body (RFC 9112, 6.3); httplib would read one until the client
        // closed, making a bare POST wait for the head deadline.
        req.headers.emplace("Content-Length", "0");
      }
    });
    if (!ok || connection_closed || unread_body || stream.ended()) break;
  }
  return ok;
}

}  // namespace dronetrack::http_api
