// dronetrack: one executable, git-style subcommands (SPEC 3.3).
#include <cstdio>
#include <exception>

#include "apps/commands.hpp"
#include "apps/signals.hpp"
#include "common/log.hpp"
#include "common/output_file.hpp"
#include "config/site_config.hpp"

namespace {

int run(int argc, char** argv) {
  using namespace dronetrack;
  guard_standard_streams();
  apps::install_stop_handlers();  // one policy for every subcommand, from the first instruction
  CLI::App root{"dronetrack: acoustic drone tracking with tetrahedral microphone arrays"};
  root.require_subcommand(1);
  root.set_version_flag("--version", std::string("dronetrack ") + DRONETRACK_VERSION);
  std::string log_level = "info";
  root.add_option("--log-level", log_level, "debug, info, warn, error or off (logs go to stderr)")
      ->capture_default_str();

  apps::CommandTable table;
  apps::register_replay(root, table);
  apps::register_node(root, table);
  apps::register_fusion(root, table);
  apps::register_alert(root, table);
  apps::register_sim(root, table);
  apps::register_eval(root, table);
  apps::register_devices(root, table);
  apps::register_demo(root, table);
  apps::register_pose_publish(root, table);
  apps::register_calibrate(root, table);
  apps::register_passwd(root, table);
  apps::register_record(root, table);

  try {
    root.parse(argc, argv);
    log::Level level{};
    if (!log::parse_level(log_level, level)) {
      throw CLI::ValidationError(
          "--log-level", "expected debug, info, warn, error or off, got \"" + log_level + "\"");
    }
    log::set_level(level);
  } catch (const CLI::CallForHelp& help) {
    return root.exit(help);
  } catch (const CLI::CallForAllHelp& help) {
    return root.exit(help);
  } catch (const CLI::CallForVersion& version) {
    return root.exit(version);
  } catch (const CLI::ParseError& failure) {
    std::fprintf(stderr, "dronetrack: error: %s (see dronetrack --help)\n", failure.what());
    return 2;
  }

  for (const auto& [subcommand, action] : table.entries()) {
    if (!subcommand->parsed()) continue;
    const std::string name = subcommand->get_name();
    try {
      return action();
    } catch (const apps::ArgumentError& failure) {
      std::fprintf(stderr, "dronetrack %s: error: %s\n", name.c_str(), failure.what());
      return 2;
    } catch (const config::ConfigError& failure) {
      for (const auto& problem : failure.problems()) {
        std::fprintf(stderr, "dronetrack %s: error: %s\n", name.c_str(), problem.c_str());
      }
      return 1;
    } catch (const std::exception& failure) {
      std::fprintf(stderr, "dronetrack %s: error: %s\n", name.c_str(), failure.what());
      return 1;
    }
  }
  return 2;
}

}  // namespace

int main(int argc, char** argv) { return run(argc, argv); }
