#pragma once
// One signal policy for every subcommand (docs/contract.md): SIGINT, SIGTERM and SIGHUP ask for a
// clean stop. Long-running loops poll stop_requested() between steps (a step never ends mid-line);
// the command then keeps its outputs as TARGET.partial and exits with 128 + the signal (130 for
// SIGINT, 143 for SIGTERM, 129 for SIGHUP). A second signal exits at once with the same code.
#include <atomic>

namespace dronetrack::apps {

// Installs the handlers (idempotent; main() does it before anything else) and returns the flag
// they set.
const std::atomic<bool>& install_stop_handlers();
bool stop_requested();
// The signal that asked for the stop, 0 if none.
int stop_signal();
// 128 + stop_signal(): the exit code of an interrupted command.
int interrupted_exit_code();
// "SIGINT", "SIGTERM", "SIGHUP".
const char* stop_signal_name();
// Sleeps until a stop is requested.
void wait_for_stop();

}  // namespace dronetrack::apps
