#pragma once
// The share of the server one client address may use (ConnectionLimits' per-client part):
// a request rate (token bucket), open event streams, failed logins per window. Thread-safe;
// the state of clients idle for a while is dropped, so the table stays bounded.
#include <chrono>
#include <cstddef>
#include <mutex>
#include <string>
#include <unordered_map>

#include "http_api/connection_limits.hpp"

namespace dronetrack::http_api {

class ClientBudget {
 public:
  using Clock = std::chrono::steady_clock;

  explicit ClientBudget(const ConnectionLimits& limits) : limits_(limits) {}

  // Takes one request from the client's allowance; false (and the seconds until one is
  // allowed again) if it is spent.
  bool take_request(const std::string& client, Clock::time_point now, double& retry_after_s);
  // True while the client has failed to log in too often in the current window (and the
  // seconds left in it).
  bool logins_blocked(const std::string& client, Clock::time_point now, double& retry_after_s);
  void login_failed(const std::string& client, Clock::time_point now);
  // One more open event stream for the client, if it has room for one.
  bool open_stream(const std::string& client);
  void close_stream(const std::string& client);

 private:
  struct State {
    double tokens = 0.0;
    Clock::time_point refilled{};
    int streams = 0;
    int failed_logins = 0;
    Clock::time_point failures_since{};
    Clock::time_point last_seen{};
  };
  State& state(const std::string& client, Clock::time_point now);
  void forget_idle(Clock::time_point now);

  const ConnectionLimits limits_;
  std::mutex mutex_;
  std::unordered_map<std::string, State> clients_;
};

}  // namespace dronetrack::http_api
