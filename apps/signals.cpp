#include "apps/signals.hpp"

#include <unistd.h>

#include <chrono>
#include <csignal>
#include <thread>

namespace dronetrack::apps {
namespace {
std::atomic<bool> stop_flag{false};
std::atomic<int> stop_signal_number{0};

extern "C" void on_stop_signal(int number) {
  // Someone pressing Ctrl-C twice wants out now: no cleanup is async-signal-safe, so _exit.
  if (stop_flag.exchange(true)) ::_exit(128 + number);
  stop_signal_number.store(number);
}
}  // namespace

const std::atomic<bool>& install_stop_handlers() {
  struct sigaction action {};
  action.sa_handler = on_stop_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: a blocking read returns EINTR and the loop sees the flag
  for (int number : {SIGINT, SIGTERM, SIGHUP}) sigaction(number, &action, nullptr);
  return stop_flag;
}

bool stop_requested() { return stop_flag.load(); }

int stop_signal() { return stop_signal_number.load(); }

int interrupted_exit_code() { return 128 + stop_signal(); }

const char* stop_signal_name() {
  switch (stop_signal()) {
    case SIGINT:
      return "SIGINT";
    case SIGTERM:
      return "SIGTERM";
    case SIGHUP:
      return "SIGHUP";
    default:
      return "a signal";
  }
}

void wait_for_stop() {
  while (!stop_flag.load()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

}  // namespace dronetrack::apps
