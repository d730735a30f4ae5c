// PLACEHOLDER: the `node` subcommand; its owner replaces this file.
#include "apps/commands.hpp"

namespace dronetrack::apps {

void register_node(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand("node", "(not implemented yet)");
  table.add(command, []() -> int { throw UserError("'node' is not implemented yet"); });
}

}  // namespace dronetrack::apps
