#include "http_api/client_budget.hpp"

#include <algorithm>

namespace dronetrack::http_api {
namespace {

// Clients idle this long are forgotten once the table holds more than kForgetAbove of them;
// by then their bucket is full again and any login window is over.
constexpr auto kIdleForget = std::chrono::minutes(10);
constexpr std::size_t kForgetAbove = 4096;

}  // namespace

ClientBudget::State& ClientBudget::state(const std::string& client, Clock::time_point now) {
  auto it = clients_.find(client);
  if (it == clients_.end()) {
    if (clients_.size() >= kForgetAbove) forget_idle(now);
    State fresh;
    fresh.tokens = limits_.request_burst_per_client;
    fresh.refilled = now;
    fresh.failures_since = now;
    it = clients_.emplace(client, fresh).first;
  }
  it->second.last_seen = now;
  return it->second;
}

void ClientBudget::forget_idle(Clock::time_point now) {
  std::erase_if(clients_, [now](const auto& entry) {
    return entry.second.streams == 0 && now - entry.second.last_seen > kIdleForget;
  });
}

bool ClientBudget::take_request(const std::string& client, Clock::time_point now,
                                double& retry_after_s) {
  std::lock_guard lock(mutex_);
  State& s = state(client, now);
  const double elapsed_s = std::chrono::duration<double>(now - s.refilled).count();
  s.tokens = std::min(limits_.request_burst_per_client,
                      s.tokens + std::max(0.0, elapsed_s) * limits_.requests_per_second_per_client);
  s.refilled = now;
  if (s.tokens >= 1.0) {
    s.tokens -= 1.0;
    return true;
  }
  retry_after_s = (1.0 - s.tokens) / limits_.requests_per_second_per_client;
  return false;
}

bool ClientBudget::logins_blocked(const std::string& client, Clock::time_point now,
                                  double& retry_after_s) {
  std::lock_guard lock(mutex_);
  State& s = state(client, now);
  const auto window_end = s.failures_since + limits_.login_failure_window;
  if (now >= window_end) {
    s.failed_logins = 0;
    s.failures_since = now;
    return false;
  }
  if (s.failed_logins < limits_.max_failed_logins_per_client) return false;
  retry_after_s = std::chrono::duration<double>(window_end - now).count();
  return true;
}

void ClientBudget::login_failed(const std::string& client, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  State& s = state(client, now);
  if (now >= s.failures_since + limits_.login_failure_window) {
    s.failed_logins = 0;
    s.failures_since = now;
  }
  ++s.failed_logins;
}

bool ClientBudget::open_stream(const std::string& client) {
  std::lock_guard lock(mutex_);
  State& s = state(client, Clock::now());
  if (s.streams >= limits_.max_streams_per_client) return false;
  ++s.streams;
  return true;
}

void ClientBudget::close_stream(const std::string& client) {
  std::lock_guard lock(mutex_);
  const auto it = clients_.find(client);
  if (it != clients_.end() && it->second.streams > 0) --it->second.streams;
}

}  // namespace dronetrack::http_api
