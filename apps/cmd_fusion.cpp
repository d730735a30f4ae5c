// PLACEHOLDER: the `fusion` subcommand; its owner replaces this file.
#include "apps/commands.hpp"

namespace dronetrack::apps {

void register_fusion(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand("fusion", "(not implemented yet)");
  table.add(command, []() -> int { throw UserError("'fusion' is not implemented yet"); });
}

}  // namespace dronetrack::apps
