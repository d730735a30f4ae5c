// `dronetrack eval`: accuracy of tracks (and DOAs) against the simulator's truth (SPEC 4.7), as a
// table on stdout and optionally as JSON. The arithmetic lives in eval/ (metrics.hpp).
#include <cstdio>
#include <memory>
#include <string>

#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/run_outputs.hpp"
#include "common/output_file.hpp"
#include "eval/metrics.hpp"
#include "eval/readers.hpp"
#include "eval/report.hpp"
#include "plot/figures.hpp"

namespace dronetrack::apps {
namespace {

struct EvalArguments {
  std::string truth;
  std::string tracks;
  std::string doas;
  std::string alerts;
  std::string json_out;
  std::string plot_out;  // HTML page of figures (docs/plots.md); "" for none
  eval::EvalOptions options;
};

// The figures' headline, as the table prints it.
std::string eval_plot_note(const eval::EvalReport& report) {
  char line[200];
  std::snprintf(line, sizeof line,
                "RMSE 3-D %.3f m over %d samples, coverage %.1f %%, %d id switches, "
                "false-track time %.1f %%; evaluated from %.2f s to %.2f s",
                report.position.rmse_3d_m, report.position.samples, 100.0 * report.coverage,
                report.id_switches, 100.0 * report.false_track_fraction, report.start_s,
                report.end_s);
  return line;
}

int run_eval(const EvalArguments& arguments) {
  std::unique_ptr<OutputFile> json_file;
  std::unique_ptr<OutputFile> plot_file;
  if (!arguments.json_out.empty() || !arguments.plot_out.empty()) {
    std::vector<NamedPath> outputs;
    if (!arguments.json_out.empty()) outputs.push_back({"--json", arguments.json_out});
    if (!arguments.plot_out.empty()) outputs.push_back({"--plot", arguments.plot_out});
    check_output_paths({{"--truth", arguments.truth},
                        {"--tracks", arguments.tracks},
                        {"--doa", arguments.doas},
                        {"--alerts", arguments.alerts}},
                       outputs);
  }
  // Opened first: an unwritable path is refused before anything is read or printed.
  if (!arguments.plot_out.empty()) plot_file = std::make_unique<OutputFile>(arguments.plot_out);
  eval::Truth truth;
  std::vector<eval::TrackRecord> tracks;
  std::vector<eval::DoaRecord> doas;
  std::vector<eval::AlertRecord> alerts;
  try {
    truth = eval::read_truth(arguments.truth);
    tracks = eval::read_tracks(arguments.tracks);
    if (!arguments.doas.empty()) doas = eval::read_doas(arguments.doas);
    if (!arguments.alerts.empty()) alerts = eval::read_alerts(arguments.alerts);
  } catch (const eval::InputError& error) {
    throw UserError(error.what());
  }
  eval::EvalReport report;
  try {
    report = eval::evaluate(truth, tracks, doas, arguments.options,
                            arguments.alerts.empty() ? nullptr : &alerts);
  } catch (const eval::InputError& error) {
    throw UserError(std::string("--tick-s: ") + error.what());
  }
  RunOutputs outputs;
  OutputFile table("-");
  outputs.add(table);
  table.write(eval::format_table(report));
  if (!arguments.json_out.empty()) {
    json_file = std::make_unique<OutputFile>(arguments.json_out);
    json_file->write(eval::to_json(report).dump(2) + "\n");
    outputs.add(*json_file);
  }
  if (plot_file) {
    std::vector<plot::Chart> charts = plot::track_charts(tracks, &truth);
    charts.push_back(plot::error_chart(report));
    if (!doas.empty()) charts.push_back(plot::doa_error_chart(report));
    plot_file->write(plot::html_page("dronetrack eval: " + arguments.tracks,
                                     {"Truth: " + arguments.truth, eval_plot_note(report)},
                                     charts));
    outputs.add(*plot_file);
  }
  return outputs.finish("eval");
}

}  // namespace

void register_eval(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand(
      "eval", "Accuracy of tracks and DOAs against simulator truth (RMSE, PFE, coverage, ...)");
  auto arguments = std::make_shared<EvalArguments>();
  command->add_option("--truth", arguments->truth, "truth.json written by `dronetrack sim`")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--tracks", arguments->tracks, "Tracks as JSON lines (SPEC 3.2)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--doa", arguments->doas, "DOAs as JSON lines: adds DOA error per array")
      ->check(CLI::ExistingFile);
  command
      ->add_option("--alerts", arguments->alerts,
                   "Alert lines (replay --alerts-out): counts zone entries by drones and by others")
      ->check(CLI::ExistingFile);
  command->add_option("--json", arguments->json_out, "Also write the report as JSON here");
  command->add_option("--plot", arguments->plot_out,
                      "Also draw the tracks against the truth, the error over time and the DOA "
                      "error per array: one self-contained HTML page here (docs/plots.md)");
  command
      ->add_option("--gate-m", arguments->options.association_gate_m,
                   "Track-to-truth association gate, metres")
      ->capture_default_str()
      ->check(finite_in(1e-3, 1e5));
  command
      ->add_option("--coverage-gate-m", arguments->options.coverage_gate_m,
                   "A source is covered when its track is within this distance, metres")
      ->capture_default_str()
      ->check(finite_in(1e-3, 1e5));
  command
      ->add_option("--converge-m", arguments->options.converge_gate_m,
                   "A source has converged once its track errors stay within this, metres")
      ->capture_default_str()
      ->check(finite_in(1e-3, 1e5));
  command
      ->add_option("--one-array-bearing-deg", arguments->options.one_array_bearing_gate_deg,
                   "A one-array track follows a source on its bearing within this angle from an "
                   "array, with the source inside its stated extent, degrees")
      ->capture_default_str()
      ->check(finite_in(1e-3, 90.0));
  command
      ->add_option("--tick-s", arguments->options.tick_s,
                   "Evaluation step, seconds (default: the tracks' output interval)")
      ->check(finite_in(0.0, 3600.0));
  command
      ->add_option("--skip-s", arguments->options.skip_s,
                   "Ignore the first seconds of the truth (e.g. sound still in flight)")
      ->capture_default_str()
      ->check(finite_in(0.0, kMaxDuration_s));
  command->add_flag("--include-tentative", arguments->options.include_tentative,
                    "Count tentative tracks as tracks");
  table.add(command, [arguments]() -> int { return run_eval(*arguments); });
}

}  // namespace dronetrack::apps
