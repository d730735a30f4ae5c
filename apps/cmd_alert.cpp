// `dronetrack alert SITE.json [--domain N] [--exec PROGRAM]`: an example DDS subscriber. Prints
// every zone alert as one JSON line on stdout and, with --exec, runs PROGRAM once per alert as
//   PROGRAM ZONE TRACK_ID entered|left TIME_S X_M Y_M Z_M
// directly (fork + execvp, no shell: nothing in an alert can be interpreted as a command).
// The program runs in the background; a slow program never delays the next alert.
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>

#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/dds_options.hpp"
#include "apps/dds_support.hpp"
#include "apps/signals.hpp"
#include "common/log.hpp"
#include "common/output_file.hpp"
#include "config/site_config.hpp"
#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"

namespace dronetrack::apps {
namespace {

struct AlertArguments {
  std::string site;
  DdsOptions dds{{}, "alert"};
  std::string exec;
  int max_alerts = 0;
  double duration_s = 0.0;
};

void run_program(const std::string& program, const fusion::ZoneEvent& event) {
  char track_id[16], time_s[32], x[32], y[32], z[32];
  std::snprintf(track_id, sizeof track_id, "%d", event.track_id);
  std::snprintf(time_s, sizeof time_s, "%.3f", event.time_s);
  std::snprintf(x, sizeof x, "%.3f", event.position_m.x());
  std::snprintf(y, sizeof y, "%.3f", event.position_m.y());
  std::snprintf(z, sizeof z, "%.3f", event.position_m.z());
  // Built before fork: the child only calls execvp and _exit (async-signal-safe).
  std::string zone = event.zone;
  std::string program_copy = program;
  std::string verb = fusion::to_string(fusion::kind_of(event));
  std::string track_class = fusion::to_string(event.track_class);
  char* argv[] = {program_copy.data(), zone.data(), track_id, verb.data(), time_s, x, y, z,
                  track_class.data(),  nullptr};
  const pid_t child = fork();
  if (child < 0) {
    log::error("alert: cannot run ", program, ": fork failed (", std::strerror(errno), ")");
    return;
  }
  if (child == 0) {
    execvp(argv[0], argv);
    // Only reached if exec failed; the parent learns it from the exit status 127.
    _exit(127);
  }
}

// Collects finished programs so none stays a zombie; reports failures.
void reap_children(const std::string& program) {
  for (;;) {
    int status = 0;
    const pid_t done = waitpid(-1, &status, WNOHANG);
    if (done <= 0) return;
    if (WIFEXITED(status) && WEXITSTATUS(status) == 127) {
      log::error("alert: ", program, " could not be run (not found or not executable)");
    } else if (WIFEXITED(status) && WEXITSTATUS(status) != 0) {
      log::warn("alert: ", program, " exited with status ", WEXITSTATUS(status));
    } else if (WIFSIGNALED(status)) {
      log::warn("alert: ", program, " killed by signal ", WTERMSIG(status));
    }
  }
}

void print_alert(const fusion::ZoneEvent& event) {
  // Zone names come from the site config; escape the two characters JSON cares about.
  std::string zone;
  for (char c : event.zone) {
    if (c == '"' || c == '\\') zone += '\\';
    if (static_cast<unsigned char>(c) >= 0x20) zone += c;
  }
  char previous[64] = "";
  if (event.kind == fusion::ZoneEventKind::class_changed)
    std::snprintf(previous, sizeof previous, R"("previous_class":"%s",)",
                  fusion::to_string(event.previous_class));
  std::printf(R"({"t":%.3f,"zone":"%s","track_id":%d,"event":"%s","class":"%s",%s)"
              R"("position_m":[%.3f,%.3f,%.3f]})"
              "\n",
              event.time_s, zone.c_str(), event.track_id, fusion::to_string(fusion::kind_of(event)),
              fusion::to_string(event.track_class), previous, event.position_m.x(),
              event.position_m.y(), event.position_m.z());
  std::fflush(stdout);
}

int run(const AlertArguments& arguments) {
  std::vector<std::string> warnings;
  config::LoadOptions load_options;
  load_options.check_recordings = false;
  const config::SiteConfig site = config::load_site_config(arguments.site, warnings, load_options);
  for (const auto& warning : warnings) log::warn(warning);
  const int domain = resolve_domain(site, arguments.dds.domain);

  const auto security = security_files(site, arguments.dds.identity);
  dds::Participant participant(domain, security ? &*security : nullptr);
  dds::Topic<dronetrack_Alert> topic(participant);
  dds::Qos qos;
  dds::alert_reader_qos(qos);
  dds::Reader<dronetrack_Alert> reader(participant, topic, qos);
  install_stop_handlers();
  log::info("alert: listening on DDS domain ", domain);

  const WallTimeLimit limit(arguments.duration_s);
  int alerts = 0;
  std::int64_t malformed = 0;
  fusion::ZoneEvent event;
  while (!stop_requested()) {
    if (limit.reached()) break;
    if (!arguments.exec.empty()) reap_children(arguments.exec);
    if (!reader.wait(std::chrono::milliseconds(100))) continue;
    dds::Samples<dronetrack_Alert> samples = reader.take();
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (!samples.info(i).valid_data) continue;
      if (dds::from_idl(samples.data(i), event) != dds::SampleProblem::none) {
        ++malformed;
        continue;
      }
      print_alert(event);
      if (!arguments.exec.empty()) run_program(arguments.exec, event);
      ++alerts;
    }
    if (arguments.max_alerts > 0 && alerts >= arguments.max_alerts) break;
  }
  if (!arguments.exec.empty()) {
    // Give the last programs a moment, then leave them to init.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (std::chrono::steady_clock::now() < deadline && waitpid(-1, nullptr, WNOHANG) >= 0) {
      reap_children(arguments.exec);
      usleep(20'000);
    }
  }
  if (malformed > 0) log::warn("alert: ", malformed, " malformed alert samples ignored");
  if (std::fflush(stdout) != 0 || std::ferror(stdout))
    throw OutputError("stdout: write failed (alerts were lost)");
  return stop_requested() ? interrupted_exit_code() : 0;
}

}  // namespace

void register_alert(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<AlertArguments>();
  auto* command = root.add_subcommand(
      "alert",
      "Print zone alerts from the fusion as JSON lines; optionally run a program per alert");
  command->add_option("site", arguments->site, "Site config (JSON, SPEC 3.1)")
      ->required()
      ->check(CLI::ExistingFile);
  add_dds_options(*command, arguments->dds, "alert");
  command->add_option("--exec", arguments->exec,
                      "Run PROGRAM ZONE TRACK_ID entered|left TIME_S X Y Z per alert (no shell)");
  command->add_option("--max-alerts", arguments->max_alerts, "Exit after this many alerts")
      ->check(CLI::NonNegativeNumber);
  add_duration_option(*command, arguments->duration_s);
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
