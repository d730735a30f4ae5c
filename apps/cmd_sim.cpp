// PLACEHOLDER: the `sim` subcommand; its owner replaces this file.
#include "apps/commands.hpp"

namespace dronetrack::apps {

void register_sim(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand("sim", "(not implemented yet)");
  table.add(command, []() -> int { throw UserError("'sim' is not implemented yet"); });
}

}  // namespace dronetrack::apps
