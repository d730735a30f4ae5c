#pragma once
// SIGINT/SIGTERM request a clean stop: long-running subcommands poll stop_requested().
#include <atomic>

namespace dronetrack::apps {

// Installs the handlers (idempotent) and returns the flag they set.
const std::atomic<bool>& install_stop_handlers();
bool stop_requested();
// Sleeps until a stop is requested.
void wait_for_stop();

}  // namespace dronetrack::apps
