#include "common/log.hpp"

#include <atomic>
#include <cstdio>
#include <mutex>

namespace dronetrack::log {
namespace {
std::atomic<Level> current_level{Level::info};
std::mutex write_mutex;
constexpr const char* kNames[] = {"debug", "info", "warn", "error", "off"};
}  // namespace

void set_level(Level new_level) { current_level.store(new_level); }
Level level() { return current_level.load(std::memory_order_relaxed); }

bool parse_level(std::string_view text, Level& out) {
  for (int i = 0; i <= static_cast<int>(Level::off); ++i) {
    if (text == kNames[i]) {
      out = static_cast<Level>(i);
      return true;
    }
  }
  return false;
}

void write(Level at, std::string_view message) {
  std::lock_guard lock(write_mutex);
  std::fprintf(stderr, "dronetrack %s: %.*s\n", kNames[static_cast<int>(at)],
               static_cast<int>(message.size()), message.data());
}

}  // namespace dronetrack::log
