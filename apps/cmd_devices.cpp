// PLACEHOLDER: the `devices` subcommand; its owner replaces this file.
#include "apps/commands.hpp"

namespace dronetrack::apps {

void register_devices(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand("devices", "(not implemented yet)");
  table.add(command, []() -> int { throw UserError("'devices' is not implemented yet"); });
}

}  // namespace dronetrack::apps
