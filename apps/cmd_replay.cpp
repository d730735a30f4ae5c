// PLACEHOLDER: the `replay` subcommand; its owner replaces this file.
#include "apps/commands.hpp"

namespace dronetrack::apps {

void register_replay(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand("replay", "(not implemented yet)");
  table.add(command, []() -> int { throw UserError("'replay' is not implemented yet"); });
}

}  // namespace dronetrack::apps
