// `dronetrack replay SITE.json --tracks-out T.jsonl --doa-out D.jsonl [--realtime --http A:P]`
#include <memory>

#include "apps/commands.hpp"
#include "apps/jsonl_output.hpp"
#include "apps/replay_runner.hpp"
#include "common/log.hpp"
#include "config/site_config.hpp"

namespace dronetrack::apps {
namespace {

struct ReplayArguments {
  std::string site;
  std::string tracks_out;
  std::string doa_out;
  bool realtime = false;
  std::string http;
  double max_duration_s = 0.0;
};

int run(const ReplayArguments& arguments) {
  std::vector<std::string> warnings;
  const config::SiteConfig site = config::load_site_config(arguments.site, warnings);
  for (const auto& warning : warnings) log::warn(warning);

  std::vector<std::unique_ptr<FusionObserver>> owned;
  if (!arguments.doa_out.empty())
    owned.push_back(std::make_unique<DoaLinesWriter>(arguments.doa_out));
  // Tracks go to stdout unless a file is named (and nothing else was asked for).
  if (!arguments.tracks_out.empty() || arguments.doa_out.empty()) {
    owned.push_back(std::make_unique<TrackLinesWriter>(
        arguments.tracks_out.empty() ? std::string("-") : arguments.tracks_out));
  }
  std::vector<FusionObserver*> observers;
  for (auto& observer : owned) observers.push_back(observer.get());

  ReplayOptions options;
  options.realtime = arguments.realtime;
  options.max_duration_s = arguments.max_duration_s;
  const ReplaySummary summary = run_replay(site, observers, options);
  log::info("replay: ", summary.stream_s, " s of audio in ", summary.wall_s, " s (",
            summary.stream_s / std::max(summary.wall_s, 1e-9), "x real time), ", summary.doas,
            " DOAs (", summary.doas_accepted, " accepted), ", summary.ticks, " track ticks");
  return 0;
}

}  // namespace

void register_replay(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<ReplayArguments>();
  auto* command = root.add_subcommand(
      "replay", "Run every array node and the fusion over the site's recordings, in one process");
  command->add_option("site", arguments->site, "Site config (JSON, SPEC 3.1)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--tracks-out", arguments->tracks_out,
                      "Write tracks as JSON lines here ('-' for stdout; default stdout)");
  command->add_option("--doa-out", arguments->doa_out,
                      "Write every array's DOAs as JSON lines here");
  command->add_flag("--realtime", arguments->realtime, "Pace the replay at real time");
  command->add_option("--http", arguments->http,
                      "Serve the web page and JSON API on ADDR:PORT (with --realtime)");
  command
      ->add_option("--max-duration-s", arguments->max_duration_s,
                   "Stop after this many seconds of recording")
      ->check(CLI::NonNegativeNumber);
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
