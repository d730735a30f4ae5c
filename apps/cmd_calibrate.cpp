// `dronetrack calibrate SITE.json --reference REF.jsonl --out SITE_CAL.json [--tdoa T.jsonl]`:
// a calibration flight's pair delays against its known positions -> a calibrated site config
// (docs/calibration.md). The solver is calib/; this file reads, reports and writes.
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>

#include "apps/calibrated_site.hpp"
#include "apps/calibration_inputs.hpp"
#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/fusion_observer.hpp"
#include "apps/replay_runner.hpp"
#include "apps/run_outputs.hpp"
#include "apps/signals.hpp"
#include "calib/channel_gains.hpp"
#include "calib/site_calibration.hpp"
#include "common/input_file.hpp"
#include "common/log.hpp"
#include "common/output_file.hpp"
#include "config/config_reader.hpp"
#include "config/site_config.hpp"

namespace dronetrack::apps {
namespace {

struct CalibrateArguments {
  std::string site;
  std::string reference;
  std::string out;
  std::string tdoa;
  std::optional<double> reference_std_m;
  std::optional<double> mic_position_std_m;
  calib::CalibrationSettings settings;
  double direction_gate_deg = 30.0;
  double max_duration_s = 0.0;
  int passes = 2;
  bool ground_echo = false;
};

// Every full-rank DOA's pair delays, as the nodes measured them, and every status's channel
// levels (per array, per second: the gains' evidence).
class TdoaCollector : public FusionObserver {
 public:
  explicit TdoaCollector(const config::SiteConfig& site)
      : levels(site.arrays.size()), site_(site) {}
  void on_doa(const doa::DoaMeasurement& doa) override {
    if (doa.ambiguity == doa::DoaAmbiguity::none) lines.push_back(tdoa_line_of(doa));
  }
  void on_node_status(const doa::NodeStatus& status) override {
    const int array = site_.array_index(status.array_id);
    if (array < 0 || status.channels.empty()) return;
    std::vector<double> stretch;
    for (const auto& channel : status.channels) stretch.push_back(channel.rms_dbfs);
    levels[static_cast<std::size_t>(array)].push_back(std::move(stretch));
  }
  std::vector<TdoaLine> lines;
  std::vector<std::vector<std::vector<double>>> levels;  // [array][second][channel], dBFS

 private:
  const config::SiteConfig& site_;
};

struct Measured {
  std::vector<TdoaLine> lines;
  std::vector<std::vector<std::vector<double>>> levels;
};

Measured measure_tdoas(config::SiteConfig site, double max_duration_s) {
  // The replay runs a fusion beside the nodes; its tracks are not used here, but one array alone
  // may only feed it with single-array starts on.
  if (site.arrays.size() == 1) site.fusion.single_array_start = true;
  TdoaCollector collector(site);
  ReplayOptions options;
  options.max_duration_s = max_duration_s;
  const ReplaySummary summary = run_replay(site, {&collector}, options, &install_stop_handlers());
  if (stop_requested()) throw UserError("interrupted before the calibration ran; nothing written");
  if (!summary.cut_short.empty()) throw UserError(summary.cut_short);
  log::info("calibrate: ", collector.lines.size(), " full-rank DOAs over ", summary.stream_s,
            " s of recordings");
  return {std::move(collector.lines), std::move(collector.levels)};
}

// The site as the calibration found it, for the next pass's nodes.
void apply_calibration(const calib::CalibrationResult& result, config::SiteConfig& site) {
  for (std::size_t a = 0; a < result.arrays.size() && a < site.arrays.size(); ++a) {
    const calib::ArrayCalibration& found = result.arrays[a];
    doa::ArrayGeometry& geometry = site.arrays[a].geometry;
    geometry.position_m = found.calibrated.position_m;
    geometry.yaw_deg = found.calibrated.yaw_deg;
    geometry.pitch_deg = found.calibrated.pitch_deg;
    geometry.roll_deg = found.calibrated.roll_deg;
    geometry.mics_m = found.calibrated.mics_m;
    geometry.channel_delay_s.clear();
    for (const calib::Estimate& delay : found.channel_delay_s)
      geometry.channel_delay_s.push_back(delay.value);
    geometry.clock_offset_s = found.clock_offset_s.value;
  }
}

int run(const CalibrateArguments& arguments) {
  std::vector<std::string> warnings;
  config::LoadOptions load_options;
  load_options.check_recordings = arguments.tdoa.empty();
  const config::SiteConfig site = config::load_site_config(arguments.site, warnings, load_options);
  for (const auto& warning : warnings) log::warn(warning);
  {
    std::vector<NamedPath> inputs = site_inputs(site, arguments.tdoa.empty());
    inputs.push_back({"--reference", arguments.reference});
    if (!arguments.tdoa.empty()) inputs.push_back({"--tdoa", arguments.tdoa});
    check_output_paths(inputs, {{"--out", arguments.out}});
  }
  for (std::size_t i = 0; i < site.arrays.size(); ++i) {
    if (site.arrays[i].moving())
      throw UserError(arguments.site + ": arrays[" + std::to_string(i) +
                      "]: a moving array (pose_file or pose_topic) is calibrated fixed, from "
                      "a flight with it standing still; remove its pose keys for the flight");
  }
  const ReferenceLog log = read_reference_log(arguments.reference);
  const calib::ReferenceTrack reference(log.samples, arguments.settings.reference_max_gap_s);
  calib::CalibrationSettings settings = arguments.settings;
  settings.speed_of_sound_mps = site.speed_of_sound_mps;
  if (arguments.ground_echo) {
    for (const auto& band : site.doa.bands_hz)
      settings.bands_hz.push_back({band.low_hz, band.high_hz});
  }
  settings.reference_position_std_m =
      arguments.reference_std_m.value_or(log.position_std_m.value_or(1.0));

  // Each pass after the first runs the nodes again with what the previous one found (channel
  // delays undone, mics where they are): a skewed channel makes the GCC take wrong cycles of
  // the rotor's harmonic, which the corrected nodes no longer do.
  const int passes = arguments.tdoa.empty() ? arguments.passes : 1;
  const std::string data_name = arguments.tdoa.empty() ? site.file.string() : arguments.tdoa;
  config::SiteConfig current = site;
  const std::vector<calib::ArrayNominal> configured =
      nominal_arrays(site, arguments.mic_position_std_m);
  calib::CalibrationResult result;
  calib::ResidualStats first_before;
  for (int pass = 1; pass <= passes; ++pass) {
    Measured measured;
    if (arguments.tdoa.empty()) {
      measured = measure_tdoas(current, arguments.max_duration_s);
    } else {
      measured.lines = read_tdoa_lines(arguments.tdoa, site);
    }
    const std::vector<TdoaLine>& lines = measured.lines;
    if (lines.empty())
      throw UserError(data_name +
                      ": no full-rank DOA with pair delays (is the calibration source "
                      "audible, are the arrays solid?)");
    const std::vector<calib::ArrayNominal> arrays =
        nominal_arrays(current, arguments.mic_position_std_m);
    int dropped = 0;
    const std::vector<calib::TdoaFrame> frames = frames_towards_reference(
        lines, arrays, reference, site.speed_of_sound_mps, arguments.direction_gate_deg, dropped);
    try {
      result = calib::calibrate_site(arrays, frames, reference, settings, &configured);
    } catch (const calib::CalibrationError& error) {
      throw UserError(arguments.reference + " with " + data_name + ": " + error.what());
    }
    if (pass == 1) first_before = result.before;
    // The raw channels' levels (the node applies a configured gain only to its spectra).
    for (std::size_t a = 0; a < result.arrays.size() && a < measured.levels.size(); ++a) {
      auto& gains = result.arrays[a].channel_gain_db;
      gains = calib::estimate_channel_gains(measured.levels[a]);
      const std::vector<double>& configured_db = site.arrays[a].geometry.channel_gain_db;
      for (std::size_t i = 0; i < gains.size() && i < configured_db.size(); ++i)
        gains[i].nominal = configured_db[i];
    }
    std::printf(
        "calibrate pass %d of %d: %zu DOAs, %d pointed beyond %g deg of the reference (another "
        "source, an echo), %d outliers; TDOA residual median |r| %.2f us -> %.2f us\n",
        pass, passes, lines.size(), dropped, arguments.direction_gate_deg, result.frames_rejected,
        result.before.median_abs_s * 1e6, result.after.median_abs_s * 1e6);
    apply_calibration(result, current);
  }
  std::printf(
      "calibrate: TDOA residual median |r| %.2f us with the site as given, %.2f us "
      "calibrated\n",
      first_before.median_abs_s * 1e6, result.after.median_abs_s * 1e6);
  std::fputs(calibration_table(result).c_str(), stdout);

  const nlohmann::ordered_json original = nlohmann::ordered_json::parse(
      read_text_file(arguments.site, config::kMaxConfigBytes, "site config"));
  const std::filesystem::path out_path(arguments.out);
  const nlohmann::ordered_json calibrated = calibrated_site_document(
      original, site, result, std::filesystem::path(arguments.site).parent_path(),
      out_path.parent_path());
  OutputFile out(out_path);
  out.write(calibrated.dump(2) + "\n");
  RunOutputs outputs;
  outputs.add(out);
  const int code = outputs.finish("calibrate");
  if (code == 0) log::info("calibrate: wrote ", arguments.out);
  return code;
}

}  // namespace

void register_calibrate(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<CalibrateArguments>();
  auto* command = root.add_subcommand(
      "calibrate",
      "Calibrate the site from a flight with known positions: array attitude and position, mic "
      "positions, channel delays, node clocks (docs/calibration.md)");
  command->add_option("site", arguments->site, "Site config (JSON, SPEC 3.1) of the flight")
      ->required()
      ->check(CLI::ExistingFile);
  command
      ->add_option("--reference", arguments->reference,
                   "The flight's known positions: JSON lines {\"t\": s, \"position_m\": [x,y,z]} "
                   "on the recordings' clock")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--out", arguments->out, "Write the calibrated site config here")->required();
  command
      ->add_option("--tdoa", arguments->tdoa,
                   "Pair delays from `replay --tdoa-out` (default: run the nodes over the site's "
                   "recordings)")
      ->check(CLI::ExistingFile);
  command
      ->add_option("--reference-std-m", arguments->reference_std_m,
                   "Position std of the reference, m (default: the lines' position_std_m, else 1)")
      ->check(finite_in(0.0, 1000.0));
  command
      ->add_option("--mic-position-std-m", arguments->mic_position_std_m,
                   "Prior std of each mic coordinate, m (default: each array's "
                   "mic_position_std_m; 0 holds the mics)")
      ->check(finite_in(0.0, 1.0));
  calib::CalibrationPriors& priors = arguments->settings.priors;
  command
      ->add_option("--attitude-std-deg", priors.attitude_std_deg,
                   "Prior std of each array's yaw, pitch and roll, degrees")
      ->capture_default_str()
      ->check(finite_in(0.0, 90.0));
  command
      ->add_option("--array-position-std-m", priors.array_position_std_m,
                   "Prior std of each array's position, m")
      ->capture_default_str()
      ->check(finite_in(0.0, 100.0));
  command
      ->add_option("--channel-delay-std-s", priors.channel_delay_std_s,
                   "Prior std of each channel's delay relative to channel 0, s")
      ->capture_default_str()
      ->check(finite_in(0.0, 0.1));
  command
      ->add_option("--clock-offset-std-s", priors.clock_offset_std_s,
                   "Prior std of each node's clock offset, s")
      ->capture_default_str()
      ->check(finite_in(0.0, 3600.0));
  command
      ->add_option("--tdoa-std-s", arguments->settings.tdoa_std_s,
                   "TDOA noise std, s (0: estimated from the residuals)")
      ->capture_default_str()
      ->check(finite_in(0.0, 0.1));
  command
      ->add_option("--direction-gate-deg", arguments->direction_gate_deg,
                   "Use a DOA only within this angle of the direction to the reference")
      ->capture_default_str()
      ->check(finite_in(0.1, 180.0));
  command
      ->add_option("--passes", arguments->passes,
                   "Run the nodes and the solver this many times, each pass's nodes with what the "
                   "previous pass found (1 with --tdoa)")
      ->capture_default_str()
      ->check(CLI::Range(1, 5));
  command->add_flag("--ground-echo", arguments->ground_echo,
                    "Fit each array's ground-echo pull on the GCC peaks (docs/calibration.md)");
  command
      ->add_option("--max-duration-s", arguments->max_duration_s,
                   "Stop reading the recordings after this many seconds")
      ->check(finite_in(0.0, kMaxDuration_s))
      ->excludes("--tdoa");
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
