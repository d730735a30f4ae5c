#pragma once
// Each subcommand lives in its own cmd_*.cpp and registers itself here: it declares its options
// on a CLI11 subcommand and returns the action main() runs when that subcommand is chosen.
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

namespace dronetrack::apps {

using CommandAction = std::function<int()>;

class CommandTable {
 public:
  void add(CLI::App* subcommand, CommandAction action) {
    entries_.emplace_back(subcommand, std::move(action));
  }
  const std::vector<std::pair<CLI::App*, CommandAction>>& entries() const { return entries_; }

 private:
  std::vector<std::pair<CLI::App*, CommandAction>> entries_;
};

// An error the user caused (bad input file, bad value): main prints it as one line and
// exits 1. Parse errors of the command line itself exit 2.
struct UserError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// An argument this site cannot honour (e.g. `--http` beyond loopback on a site without TLS and
// users): main prints it as one line and exits 2, like a command-line error.
struct ArgumentError : UserError {
  using UserError::UserError;
};

void register_replay(CLI::App& root, CommandTable& table);
void register_node(CLI::App& root, CommandTable& table);
void register_fusion(CLI::App& root, CommandTable& table);
void register_alert(CLI::App& root, CommandTable& table);
void register_sim(CLI::App& root, CommandTable& table);
void register_eval(CLI::App& root, CommandTable& table);
void register_devices(CLI::App& root, CommandTable& table);
void register_demo(CLI::App& root, CommandTable& table);
void register_pose_publish(CLI::App& root, CommandTable& table);
void register_calibrate(CLI::App& root, CommandTable& table);
void register_passwd(CLI::App& root, CommandTable& table);
void register_record(CLI::App& root, CommandTable& table);

}  // namespace dronetrack::apps
