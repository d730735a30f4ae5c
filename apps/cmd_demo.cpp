// PLACEHOLDER: the `demo` subcommand; its owner replaces this file.
#include "apps/commands.hpp"

namespace dronetrack::apps {

void register_demo(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand("demo", "(not implemented yet)");
  table.add(command, []() -> int { throw UserError("'demo' is not implemented yet"); });
}

}  // namespace dronetrack::apps
