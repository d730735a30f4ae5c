#include "apps/signals.hpp"

#include <chrono>
#include <csignal>
#include <thread>

namespace dronetrack::apps {
namespace {
std::atomic<bool> stop_flag{false};
extern "C" void on_stop_signal(int) { stop_flag.store(true); }
}  // namespace

const std::atomic<bool>& install_stop_handlers() {
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  return stop_flag;
}

bool stop_requested() { return stop_flag.load(); }

void wait_for_stop() {
  while (!stop_flag.load()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
}

}  // namespace dronetrack::apps
