#pragma once
// A raw TCP client for the HTTP server tests: it sends exactly the bytes it is given (a head a
// line at a time, pipelined requests) from a chosen loopback source address, and tells when the
// server has closed the connection.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>

namespace dronetrack::http_api::test {

class RawClient {
 public:
  using Clock = std::chrono::steady_clock;

  // Connects to 127.0.0.1:`port` from `source` (any 127/8 address is local on Linux; the
  // server counts its per-address limit by it). connected() says whether it worked.
  RawClient(int port, const char* source = "127.0.0.1") {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in local{};
    local.sin_family = AF_INET;
    ::inet_pton(AF_INET, source, &local.sin_addr);
    sockaddr_in server{};
    server.sin_family = AF_INET;
    server.sin_port = htons(static_cast<std::uint16_t>(port));
    server.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = fd_ >= 0 && ::bind(fd_, reinterpret_cast<sockaddr*>(&local), sizeof(local)) == 0 &&
                 ::connect(fd_, reinterpret_cast<sockaddr*>(&server), sizeof(server)) == 0;
    if (!connected_) closed_ = true;
  }
  ~RawClient() {
    if (fd_ >= 0) ::close(fd_);
  }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;

  bool connected() const { return connected_; }
  bool closed() const { return closed_; }
  Clock::time_point closed_at() const { return closed_at_; }
  const std::string& received() const { return received_; }
  // The status of the first response received, or 0.
  int status() const {
    if (received_.size() < 12 || received_.compare(0, 5, "HTTP/") != 0) return 0;
    return std::stoi(received_.substr(9, 3));
  }

  // Sends all of `text`; false if the server has closed the connection.
  bool send(std::string_view text) {
    if (closed_) return false;
    while (!text.empty()) {
      const ssize_t n = ::send(fd_, text.data(), text.size(), MSG_NOSIGNAL);
      if (n <= 0) {
        mark_closed();
        return false;
      }
      text.remove_prefix(static_cast<std::size_t>(n));
    }
    return true;
  }

  // Collects what the server sent within `wait`; notes when it closed the connection (end of
  // stream or reset). Returns as soon as something arrives.
  void pump(std::chrono::milliseconds wait = std::chrono::milliseconds(0)) {
    if (closed_) return;
    pollfd entry{fd_, POLLIN, 0};
    if (::poll(&entry, 1, static_cast<int>(wait.count())) <= 0) return;
    char buffer[4096];
    for (;;) {
      const ssize_t n = ::recv(fd_, buffer, sizeof(buffer), MSG_DONTWAIT);
      if (n > 0) {
        received_.append(buffer, static_cast<std::size_t>(n));
        continue;
      }
      if (n == 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) mark_closed();
      return;
    }
  }

  // Pumps until `done()` holds or `timeout` passes; returns done().
  template <typename Done>
  bool pump_until(Done done, std::chrono::milliseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (!done() && !closed_ && Clock::now() < deadline) pump(std::chrono::milliseconds(10));
    return done();
  }
  bool wait_closed(std::chrono::milliseconds timeout) {
    return pump_until([this] { return closed_; }, timeout);
  }

 private:
  void mark_closed() {
    closed_ = true;
    closed_at_ = Clock::now();
  }

  int fd_ = -1;
  bool connected_ = false;
  bool closed_ = false;
  Clock::time_point closed_at_{};
  std::string received_;
};

}  // namespace dronetrack::http_api::test
