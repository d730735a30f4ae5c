// `dronetrack replay SITE.json --tracks-out T.jsonl --doa-out D.jsonl [--realtime --http A:P]`
// `dronetrack replay SITE.json --doa-in D.jsonl --tracks-out T.jsonl`: the fusion alone
#include <memory>

#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/replay_session.hpp"
#include "common/log.hpp"
#include "config/site_config.hpp"
#include "eval/readers.hpp"

namespace dronetrack::apps {
namespace {

struct ReplayArguments {
  std::string site;
  ReplaySessionOptions session;
  bool exit_when_done = false;
};

int run(ReplayArguments arguments) {
  std::vector<std::string> warnings;
  config::LoadOptions load_options;
  load_options.check_recordings = arguments.session.doa_in.empty();  // not read then
  load_options.for_fusion = true;
  const config::SiteConfig site = config::load_site_config(arguments.site, warnings, load_options);
  for (const auto& warning : warnings) log::warn(warning);
  arguments.session.keep_serving = !arguments.exit_when_done;
  return run_replay_session(site, arguments.session);
}

}  // namespace

void register_replay(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<ReplayArguments>();
  auto* command = root.add_subcommand(
      "replay", "Run every array node and the fusion over the site's recordings, in one process");
  command->add_option("site", arguments->site, "Site config (JSON, SPEC 3.1)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--tracks-out", arguments->session.tracks_out,
                      "Write tracks as JSON lines here ('-' for stdout; default stdout)");
  command->add_option("--doa-out", arguments->session.doa_out,
                      "Write every array's DOAs as JSON lines here");
  command->add_option("--tdoa-out", arguments->session.tdoa_out,
                      "Write every full-rank DOA's pair delays as JSON lines here (for "
                      "calibrate --tdoa; docs/calibration.md)");
  command->add_option("--alerts-out", arguments->session.alerts_out,
                      "Write zone alerts and track class changes as JSON lines here");
  command->add_option("--plot", arguments->session.plot_out,
                      "Draw the tracks (plan view, altitude) and every array's DOAs over time: "
                      "one self-contained HTML page here (docs/plots.md)");
  auto* realtime =
      command->add_flag("--realtime", arguments->session.realtime, "Pace the replay at real time");
  auto* doa_in =
      command
          ->add_option(
              "--doa-in", arguments->session.doa_in,
              "Run the fusion alone on these DOA lines (a replay's --doa-out) instead of the "
              "recordings")
          ->check(CLI::ExistingFile)
          ->excludes(realtime);
  command
      ->add_option("--audio-end-s", arguments->session.doa_in_audio_end_s,
                   "With --doa-in: the end of the audio the DOAs were made from, seconds on the "
                   "DOAs' clock; the tracks are reported up to it, as a replay of that audio "
                   "does (default: up to the last DOA)")
      ->check(finite_in(-eval::kMaxAbsoluteTime_s, eval::kMaxAbsoluteTime_s))
      ->needs(doa_in);
  auto* outliers =
      command
          ->add_option("--doa-outliers", arguments->session.doa_outliers.share,
                       "With --doa-in: make this share of the DOAs outliers, alpha-stable angular "
                       "errors on azimuth and elevation (fusion-only experiments; docs/fusion.md)")
          ->check(finite_in(0.0, 1.0))
          ->needs(doa_in);
  command
      ->add_option("--doa-outlier-alpha", arguments->session.doa_outliers.law_deg.alpha,
                   "Stability of the outlier errors (2 Gaussian, 1 Cauchy)")
      ->capture_default_str()
      ->check(finite_in(0.1, 2.0))
      ->needs(outliers);
  command
      ->add_option("--doa-outlier-scale-deg", arguments->session.doa_outliers.law_deg.scale,
                   "Scale of the outlier errors, degrees")
      ->capture_default_str()
      ->check(finite_in(1e-3, 90.0))
      ->needs(outliers);
  command
      ->add_option("--doa-outlier-seed", arguments->session.doa_outliers.seed,
                   "Seed of the outlier draws")
      ->capture_default_str()
      ->needs(outliers);
  command
      ->add_option("--http", arguments->session.http,
                   "Serve the web page and JSON API on ADDR:PORT (e.g. 127.0.0.1:8080); keeps "
                   "serving after the recordings end until Ctrl-C")
      ->check(http_address());
  command->add_flag("--exit-when-done", arguments->exit_when_done,
                    "With --http: exit when the recordings end instead of serving on");
  command
      ->add_option("--max-duration-s", arguments->session.max_duration_s,
                   "Stop after this many seconds of recording")
      ->check(finite_in(0.0, kMaxDuration_s))
      ->excludes(doa_in);
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
