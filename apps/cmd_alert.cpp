// PLACEHOLDER: the `alert` subcommand; its owner replaces this file.
#include "apps/commands.hpp"

namespace dronetrack::apps {

void register_alert(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand("alert", "(not implemented yet)");
  table.add(command, []() -> int { throw UserError("'alert' is not implemented yet"); });
}

}  // namespace dronetrack::apps
