// PLACEHOLDER: the `eval` subcommand; its owner replaces this file.
#include "apps/commands.hpp"

namespace dronetrack::apps {

void register_eval(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand("eval", "(not implemented yet)");
  table.add(command, []() -> int { throw UserError("'eval' is not implemented yet"); });
}

}  // namespace dronetrack::apps
