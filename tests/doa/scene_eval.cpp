#include "tests/doa/scene_eval.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>

#include "doa/gcc_phat.hpp"
#include "doa/node_pipeline.hpp"
#include "doa/spectral_frame.hpp"

namespace dronetrack::doa::testing {

namespace {

double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return std::nan("");
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(std::floor(fraction * (values.size() - 1) + 0.5));
  return values[std::min(index, values.size() - 1)];
}

// Truth direction of a source at an array at time t (linear interpolation of the 100 Hz table).
Eigen::Vector3d truth_direction(const sim::SourceTruth& source, std::size_t array, double time_s) {
  const std::vector<double>& times = source.t_s;
  const std::vector<Eigen::Vector3d>& directions = source.direction[array];
  if (time_s <= times.front()) return directions.front();
  if (time_s >= times.back()) return directions.back();
  const auto upper = std::upper_bound(times.begin(), times.end(), time_s);
  const auto index = static_cast<std::size_t>(upper - times.begin());
  const double fraction = (time_s - times[index - 1]) / (times[index] - times[index - 1]);
  return (directions[index - 1] * (1.0 - fraction) + directions[index] * fraction).normalized();
}

// Power of each band bin of each analysis frame of interleaved audio, summed over the channels
// (same frames and bins as the pipeline): frame-major, `bins_per_frame` values a frame.
struct FrameBinPowers {
  std::size_t bins_per_frame = 0;
  std::vector<double> values;
  std::size_t frames() const { return bins_per_frame > 0 ? values.size() / bins_per_frame : 0; }
  const double* frame(std::size_t k) const { return values.data() + k * bins_per_frame; }
  double band_power(std::size_t k) const {
    double total = 0.0;
    for (std::size_t b = 0; b < bins_per_frame; ++b) total += frame(k)[b];
    return total;
  }
};

FrameBinPowers frame_bin_powers(const std::vector<float>& samples, std::size_t channels,
                                double sample_rate_hz, const DoaParams& params) {
  const int frame_length = static_cast<int>(std::lround(params.frame_s * sample_rate_hz));
  const int hop = std::max(1, static_cast<int>(std::lround(params.hop_s * sample_rate_hz)));
  Framer framer(static_cast<int>(channels), frame_length, hop);
  MultichannelFft fft(static_cast<int>(channels), frame_length, fftw_friendly_size(frame_length));
  const std::vector<BandRun> runs = band_runs(params.bands_hz, sample_rate_hz, fft.fft_size());
  FrameBinPowers powers;
  for (const BandRun& run : runs)
    powers.bins_per_frame += static_cast<std::size_t>(run.last_bin - run.first_bin + 1);
  const AudioBlockView block{0, static_cast<int>(channels), samples.size() / channels,
                             samples.data()};
  framer.push(block, [&](const FrameView& frame) {
    fft.process(frame);
    const std::size_t first = powers.values.size();
    powers.values.resize(first + powers.bins_per_frame, 0.0);
    for (int c = 0; c < fft.channels(); ++c) {
      std::size_t b = first;
      for (const BandRun& run : runs)
        for (int k = run.first_bin; k <= run.last_bin; ++k)
          powers.values[b++] += std::norm(fft.spectrum(c)[k]);
    }
  });
  return powers;
}

double ratio_db(double signal, double noise) {
  return 10.0 * std::log10(std::max(signal, 1e-30) / std::max(noise, 1e-30));
}

// SNR on the drone's own comb: the band bins where the drone alone stands at least
// kCombAboveMedianDb above its own median band bin (its harmonics, not its broadband floor),
// the drone's power there against everything else's power in the same bins. It is the SNR a
// receiver that keeps only the drone's bins would see; it does not depend on the interferers'
// spectra to choose the bins.
constexpr double kCombAboveMedianDb = 10.0;
// The least power of a comb bin of the drone's frame.
double comb_threshold(const double* drone, std::size_t bins, std::vector<double>& scratch) {
  scratch.assign(drone, drone + bins);
  std::nth_element(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(bins / 2),
                   scratch.end());
  return scratch[bins / 2] * std::pow(10.0, kCombAboveMedianDb / 10.0);
}

double comb_snr_db(const double* drone, const double* others, std::size_t bins,
                   std::vector<double>& scratch) {
  const double threshold = comb_threshold(drone, bins, scratch);
  double signal = 0.0;
  double noise = 0.0;
  for (std::size_t b = 0; b < bins; ++b) {
    if (drone[b] < threshold) continue;
    signal += drone[b];
    noise += others[b];
  }
  return signal > 0.0 ? ratio_db(signal, noise) : -100.0;
}

// The share of the drone's comb power (its bins kCombAboveMedianDb over its median) in
// the bins a mask keeps.
double comb_share_kept(const double* drone, std::size_t bins, const std::vector<std::uint8_t>& keep,
                       std::vector<double>& scratch) {
  const double threshold = comb_threshold(drone, bins, scratch);
  double all = 0.0;
  double kept = 0.0;
  for (std::size_t b = 0; b < bins && b < keep.size(); ++b) {
    if (drone[b] < threshold) continue;
    all += drone[b];
    kept += keep[b] != 0 ? drone[b] : 0.0;
  }
  return all > 0.0 ? kept / all : 1.0;
}

class TraceCollector final : public FrameTraceSink {
 public:
  std::vector<FrameTrace> frames;
  void frame(const FrameTrace& trace) override { frames.push_back(trace); }
};

// --frames: one array's frames in a window as the trace saw them, against the truth.
void print_traced_frames(const std::vector<FrameTrace>& frames, const sim::Truth& truth,
                         std::size_t array, const EvaluationSettings& settings) {
  for (const FrameTrace& trace : frames) {
    if (trace.time_s < settings.frames_from_s || trace.time_s > settings.frames_to_s) continue;
    std::printf("frame %.4f s%s%s, search %s, comb look line bins %d\n", trace.time_s,
                trace.sharp ? "" : " (not sharp)", trace.detecting ? "" : " (gate closed)",
                name(trace.search_end), trace.comb_line_bins);
    for (const sim::SourceTruth& source : truth.sources) {
      const Eigen::Vector3d direction = truth_direction(source, array, trace.time_s);
      std::printf("  truth %-4s az %8.2f el %6.2f\n", source.id.c_str(), azimuth_deg(direction),
                  elevation_deg(direction));
    }
    for (int l = 0; l < trace.look_count; ++l) {
      const LookTrace& look = trace.looks[static_cast<std::size_t>(l)];
      std::printf("  look %-8s %-13s az %8.2f el %6.2f\n", name(look.kind), name(look.outcome),
                  azimuth_deg(look.direction_site), elevation_deg(look.direction_site));
    }
    for (int c = 0; c < trace.candidate_count; ++c) {
      const Eigen::Vector3d& direction = trace.candidates[static_cast<std::size_t>(c)];
      std::printf("  candidate    az %8.2f el %6.2f\n", azimuth_deg(direction),
                  elevation_deg(direction));
    }
  }
  std::fflush(stdout);
}

// Beyond this a look or candidate is another source, not the drone's fringe or bias.
constexpr double kOffTargetDeg = 20.0;

// The first cause, in pipeline order, of a miss (docs/doa.md "Where the drones' frames go").
MissCause miss_cause(const FrameTrace& trace, const Eigen::Vector3d& truth, double comb_after_null,
                     double comb_at_search_end, double within_deg, FrameAudibility& frame) {
  if (!trace.sharp) return MissCause::not_sharp;
  if (comb_after_null < 0.5) return MissCause::null_dropped;
  for (int c = 0; c < trace.candidate_count; ++c)
    if (angle_between_deg(trace.candidates[static_cast<std::size_t>(c)], truth) <= within_deg)
      return trace.detecting ? MissCause::regression : MissCause::gate_closed;
  bool kept_within = false;
  for (int l = 0; l < trace.look_count; ++l) {
    const LookTrace& look = trace.looks[static_cast<std::size_t>(l)];
    if (angle_between_deg(look.direction_site, truth) > within_deg) continue;
    switch (look.outcome) {
      case LookOutcome::kept:
        kept_within = true;
        break;
      case LookOutcome::refused_pairs:
        return MissCause::refused_pairs;
      case LookOutcome::refused_norm:
        return MissCause::refused_norm;
      case LookOutcome::refused_chi2:
        return MissCause::refused_chi2;
      case LookOutcome::duplicate:
        return MissCause::duplicate;
      case LookOutcome::below_horizon:
        return MissCause::below_horizon;
    }
  }
  if (kept_within) return MissCause::remeasure_moved;
  double nearest = 180.0;
  auto consider = [&](const Eigen::Vector3d& direction, int kind, bool kept) {
    const double angle = angle_between_deg(direction, truth);
    if (angle >= nearest) return;
    nearest = angle;
    frame.off_deg = angle;
    frame.off_elevation_deg = elevation_deg(direction) - elevation_deg(truth);
    frame.off_kind = kind;
    frame.off_kept = kept;
  };
  for (int c = 0; c < trace.candidate_count; ++c)
    consider(trace.candidates[static_cast<std::size_t>(c)], -1, true);
  for (int l = 0; l < trace.look_count; ++l) {
    const LookTrace& look = trace.looks[static_cast<std::size_t>(l)];
    consider(look.direction_site, static_cast<int>(look.kind), look.outcome == LookOutcome::kept);
  }
  if (nearest <= kOffTargetDeg) return MissCause::off_target;
  if (trace.search_end == SearchEnd::capacity) return MissCause::capacity;
  if (comb_at_search_end < 0.5) return MissCause::owned_by_others;
  if (trace.search_end == SearchEnd::under_floor) return MissCause::under_floor;
  if (trace.search_end == SearchEnd::looks_spent) return MissCause::looks_spent;
  return MissCause::other;
}

}  // namespace

const char* miss_cause_name(MissCause cause) {
  static constexpr std::array<const char*, static_cast<std::size_t>(MissCause::count)> kNames{
      "found",           "not sharp",    "gate closed",  "null dropped",    "regression",
      "refused pairs",   "refused norm", "refused chi2", "duplicate",       "below horizon",
      "remeasure moved", "off 3-20 deg", "capacity",     "owned by others", "under SRP floor",
      "looks spent",     "other"};
  return kNames[static_cast<std::size_t>(cause)];
}

double DroneAtArray::median_deg() const { return percentile(errors_deg, 0.5); }
double DroneAtArray::p90_deg() const { return percentile(errors_deg, 0.9); }

RenderedScenario render_for_evaluation(const sim::Scenario& scenario) {
  RenderedScenario rendered;
  rendered.scenario = scenario;
  rendered.truth = sim::compute_truth(scenario);
  const std::size_t arrays = scenario.site.arrays.size();
  for (std::size_t a = 0; a < arrays; ++a) rendered.full.push_back(sim::render_array(scenario, a));
  for (std::size_t s = 0; s < scenario.sources.size(); ++s) {
    if (scenario.sources[s].kind != sim::SourceKind::drone) continue;
    // Silence the other sources instead of removing them: a source's random streams follow its
    // index in the scenario, so removing one would change the others' signals.
    sim::Scenario alone = scenario;
    for (std::size_t other = 0; other < alone.sources.size(); ++other)
      if (other != s) alone.sources[other].level_db_spl = -400.0;
    alone.noise.sensor.enabled = false;
    alone.noise.wind.enabled = false;
    alone.noise.ambient.enabled = false;
    std::vector<sim::RenderedArray> per_array;
    for (std::size_t a = 0; a < arrays; ++a) per_array.push_back(sim::render_array(alone, a));
    rendered.drone_alone.push_back(std::move(per_array));
  }
  sim::Scenario interferers = scenario;
  bool any_interferer = false;
  for (sim::SourceSpec& source : interferers.sources) {
    if (source.kind == sim::SourceKind::drone) source.level_db_spl = -400.0;
    any_interferer = any_interferer || source.kind != sim::SourceKind::drone;
  }
  interferers.noise.sensor.enabled = false;
  interferers.noise.wind.enabled = false;
  interferers.noise.ambient.enabled = false;
  for (std::size_t a = 0; a < arrays; ++a) {
    if (!any_interferer) {
      sim::RenderedArray silent = rendered.full[a];
      std::fill(silent.samples.begin(), silent.samples.end(), 0.0F);
      rendered.interferers_alone.push_back(std::move(silent));
    } else {
      rendered.interferers_alone.push_back(sim::render_array(interferers, a));
    }
  }
  return rendered;
}

SceneResult evaluate(const RenderedScenario& rendered, const DoaParams& params,
                     const EvaluationSettings& settings) {
  const sim::Scenario& scenario = rendered.scenario;
  SceneResult result;
  std::vector<std::size_t> drone_truth;  // index into truth.sources per drone
  for (std::size_t s = 0; s < rendered.truth.sources.size(); ++s)
    if (rendered.truth.sources[s].is_drone) drone_truth.push_back(s);

  for (std::size_t a = 0; a < rendered.full.size(); ++a) {
    const sim::RenderedArray& full = rendered.full[a];
    const ArrayGeometry& geometry = scenario.site.arrays[a].geometry;
    // Noise (everything that is not a drone) = full scene minus every drone's own rendering.
    std::vector<float> noise = full.samples;
    for (const auto& drone : rendered.drone_alone)
      for (std::size_t n = 0; n < noise.size(); ++n) noise[n] -= drone[a].samples[n];
    for (std::size_t n = 0; n < noise.size(); ++n)
      noise[n] -= rendered.interferers_alone[a].samples[n];
    const FrameBinPowers noise_power =
        frame_bin_powers(noise, full.channels, full.sample_rate_hz, params);

    NodePipeline pipeline(geometry, static_cast<int>(a), params, full.sample_rate_hz,
                          scenario.site.speed_of_sound_mps);
    TraceCollector traces;
    const bool print_frames = settings.frames_array == geometry.id;
    if (settings.breakdown || print_frames) pipeline.set_frame_trace(&traces);
    std::vector<DoaMeasurement> doas;
    doas.reserve(8192);
    const auto start = std::chrono::steady_clock::now();
    constexpr std::size_t kBlock = 1024;
    for (std::size_t first = 0; first < full.frames(); first += kBlock) {
      const std::size_t count = std::min(kBlock, full.frames() - first);
      pipeline.process({static_cast<std::int64_t>(first), static_cast<int>(full.channels), count,
                        full.samples.data() + first * full.channels},
                       doas);
    }
    result.seconds_cpu +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    result.seconds_processed += static_cast<double>(full.frames()) / full.sample_rate_hz;
    result.doas += static_cast<int>(doas.size());

    const int frame_length = pipeline.frame_length_samples();
    const int hop = pipeline.hop_samples();
    auto frame_of = [&](double time_s) {
      return static_cast<int>(
          std::lround((time_s * full.sample_rate_hz - 0.5 * (frame_length - 1)) / hop));
    };
    if (print_frames) print_traced_frames(traces.frames, rendered.truth, a, settings);
    std::multimap<int, const DoaMeasurement*> by_frame;
    for (const DoaMeasurement& doa : doas) by_frame.emplace(frame_of(doa.time_s), &doa);
    std::map<int, const FrameTrace*> trace_of;
    for (const FrameTrace& trace : traces.frames) trace_of[frame_of(trace.time_s)] = &trace;

    // Stray DOAs: near no source at all (drones and interferers).
    for (const DoaMeasurement& doa : doas) {
      bool near_any = false;
      for (const sim::SourceTruth& source : rendered.truth.sources)
        near_any =
            near_any || angle_between_deg(doa.direction, truth_direction(source, a, doa.time_s)) <=
                            settings.found_within_deg;
      result.stray_doas += near_any ? 0 : 1;
      if (!near_any && std::getenv("DOA_SCENE_EVAL_VERBOSE") != nullptr) {
        const Eigen::Vector3d truth =
            truth_direction(rendered.truth.sources.front(), a, doa.time_s);
        std::fprintf(stderr,
                     "stray %s t=%.2f src=%d az=%.2f el=%.2f (truth %.2f %.2f) q=%.2f snr=%.1f\n",
                     geometry.id.c_str(), doa.time_s, doa.source_index, azimuth_deg(doa.direction),
                     elevation_deg(doa.direction), azimuth_deg(truth), elevation_deg(truth),
                     doa.quality, doa.snr_db);
      }
    }

    for (std::size_t d = 0; d < drone_truth.size(); ++d) {
      const sim::SourceTruth& source = rendered.truth.sources[drone_truth[d]];
      const FrameBinPowers drone_power = frame_bin_powers(
          rendered.drone_alone[d][a].samples, full.channels, full.sample_rate_hz, params);
      // Everything but this drone: the full scene minus its own rendering.
      FrameBinPowers others_power;
      if (settings.audibility) {
        std::vector<float> others = full.samples;
        for (std::size_t n = 0; n < others.size(); ++n)
          others[n] -= rendered.drone_alone[d][a].samples[n];
        others_power = frame_bin_powers(others, full.channels, full.sample_rate_hz, params);
      }
      DroneAtArray cell;
      cell.drone_id = source.id;
      cell.array_id = geometry.id;
      std::vector<double> scratch;
      const std::size_t frames = std::min(drone_power.frames(), noise_power.frames());
      for (std::size_t k = 0; k < frames; ++k) {
        const double snr_db = ratio_db(drone_power.band_power(k), noise_power.band_power(k));
        const double time_s =
            (static_cast<double>(k) * hop + 0.5 * (frame_length - 1)) / full.sample_rate_hz;
        const Eigen::Vector3d truth = truth_direction(source, a, time_s);
        double best = 180.0;
        double best_elevation_error = 0.0;
        const auto range = by_frame.equal_range(static_cast<int>(k));
        for (auto it = range.first; it != range.second; ++it) {
          const double error = angle_between_deg(it->second->direction, truth);
          if (error >= best) continue;
          best = error;
          best_elevation_error = elevation_deg(it->second->direction) - elevation_deg(truth);
        }
        FrameAudibility audibility;
        audibility.background_snr_db = snr_db;
        if (settings.audibility) {
          audibility.band_snr_db = ratio_db(drone_power.band_power(k), others_power.band_power(k));
          audibility.comb_snr_db = comb_snr_db(drone_power.frame(k), others_power.frame(k),
                                               drone_power.bins_per_frame, scratch);
        }
        audibility.error_deg = best;
        audibility.elevation_error_deg = best_elevation_error;
        audibility.truth_elevation_deg = elevation_deg(truth);
        const auto traced = trace_of.find(static_cast<int>(k));
        if (settings.breakdown && settings.audibility && best > settings.found_within_deg &&
            traced != trace_of.end()) {
          const FrameTrace& trace = *traced->second;
          const std::size_t bins = drone_power.bins_per_frame;
          audibility.cause = miss_cause(
              trace, truth,
              comb_share_kept(drone_power.frame(k), bins, trace.kept_after_null, scratch),
              comb_share_kept(drone_power.frame(k), bins, trace.kept_at_search_end, scratch),
              settings.found_within_deg, audibility);
          if (audibility.cause == MissCause::under_floor) {
            audibility.kept_bins = trace.search_end_kept_bins;
            audibility.floor_ratio = trace.search_end_best_power / trace.search_end_floor;
            audibility.comb_line_bins = trace.comb_line_bins;
            if (trace.comb_line_bins > 0)
              audibility.comb_floor_ratio = trace.comb_look_best_power / trace.comb_look_floor;
          }
        }
        cell.frames.push_back(audibility);
        cell.max_snr_db = std::max(cell.max_snr_db, snr_db);
        if (snr_db < settings.audible_snr_db) continue;
        ++cell.audible_frames;
        if (best <= settings.found_within_deg) {
          ++cell.found_frames;
          cell.errors_deg.push_back(best);
        }
      }
      result.cells.push_back(std::move(cell));
    }
  }
  return result;
}

std::string format_audibility_rows(const std::string& scene, const SceneResult& result,
                                   double found_within_deg) {
  std::string rows;
  char line[384];
  for (const DroneAtArray& cell : result.cells) {
    std::string columns;
    auto add = [&](auto&& audible) {
      int heard = 0;
      int found = 0;
      for (const FrameAudibility& frame : cell.frames) {
        if (!audible(frame)) continue;
        ++heard;
        found += frame.error_deg <= found_within_deg ? 1 : 0;
      }
      char column[64];
      std::snprintf(column, sizeof column, " %d, %.1f %% |", heard,
                    heard > 0 ? 100.0 * found / heard : 0.0);
      columns += column;
    };
    add([](const FrameAudibility&) { return true; });
    for (const double threshold_db : {0.0, 6.0})
      add([threshold_db](const FrameAudibility& f) { return f.background_snr_db >= threshold_db; });
    for (const double threshold_db : {0.0, 6.0})
      add([threshold_db](const FrameAudibility& f) { return f.band_snr_db >= threshold_db; });
    for (const double threshold_db : {0.0, 6.0})
      add([threshold_db](const FrameAudibility& f) { return f.comb_snr_db >= threshold_db; });
    std::vector<double> elevation_errors;
    for (const FrameAudibility& frame : cell.frames)
      if (frame.error_deg <= found_within_deg)
        elevation_errors.push_back(frame.elevation_error_deg);
    std::snprintf(line, sizeof line, "| %s | %s | %s |%s %+.2f |\n", scene.c_str(),
                  cell.array_id.c_str(), cell.drone_id.c_str(), columns.c_str(),
                  percentile(elevation_errors, 0.5));
    rows += line;
  }
  return rows;
}

std::string format_breakdown_rows(const std::string& scene, const SceneResult& result,
                                  double found_within_deg) {
  constexpr auto kCauses = static_cast<std::size_t>(MissCause::count);
  std::string rows = "| scene | array | drone | comb >= 0 dB | found |";
  for (std::size_t c = 1; c < kCauses; ++c)
    rows += std::string(" ") + miss_cause_name(static_cast<MissCause>(c)) + " |";
  rows +=
      " off: 3-6 / 6-9 / 9-14 / 14-20 deg, median el | off: candidate / primary / followed / free "
      "/ static / comb kept, refused | drone el | floor: kept bins, best / floor (medians) | "
      "floor: comb looks, line bins, best / floor (medians) |\n|---|---|---|---|---|";
  for (std::size_t c = 1; c < kCauses; ++c) rows += "---|";
  rows += "---|---|---|---|---|\n";
  char line[128];
  for (const DroneAtArray& cell : result.cells) {
    std::array<int, kCauses> counts{};
    std::array<int, 4> off{};
    std::vector<double> off_elevations;
    std::vector<double> truth_elevations;
    std::array<int, 7> off_kinds{};
    std::vector<double> kept_bins;
    std::vector<double> floor_ratios;
    std::vector<double> comb_line_bins;
    std::vector<double> comb_floor_ratios;
    int heard = 0;
    int found = 0;
    for (const FrameAudibility& frame : cell.frames) {
      if (frame.comb_snr_db < 0.0) continue;
      ++heard;
      if (frame.error_deg <= found_within_deg) {
        ++found;
        continue;
      }
      ++counts[static_cast<std::size_t>(frame.cause)];
      if (frame.cause == MissCause::under_floor) {
        kept_bins.push_back(frame.kept_bins);
        floor_ratios.push_back(frame.floor_ratio);
        if (frame.comb_line_bins > 0) {
          comb_line_bins.push_back(frame.comb_line_bins);
          comb_floor_ratios.push_back(frame.comb_floor_ratio);
        }
      }
      if (frame.cause != MissCause::off_target) continue;
      off[frame.off_deg < 6.0 ? 0 : frame.off_deg < 9.0 ? 1 : frame.off_deg < 14.0 ? 2 : 3] += 1;
      off_elevations.push_back(frame.off_elevation_deg);
      off_kinds[frame.off_kept ? static_cast<std::size_t>(frame.off_kind + 1) : 6] += 1;
    }
    for (const FrameAudibility& frame : cell.frames)
      truth_elevations.push_back(frame.truth_elevation_deg);
    std::snprintf(line, sizeof line, "| %s | %s | %s | %d | %d |", scene.c_str(),
                  cell.array_id.c_str(), cell.drone_id.c_str(), heard, found);
    rows += line;
    for (std::size_t c = 1; c < kCauses; ++c) {
      std::snprintf(line, sizeof line, " %d |", counts[c]);
      rows += line;
    }
    std::snprintf(line, sizeof line, " %d / %d / %d / %d, %+.1f |", off[0], off[1], off[2], off[3],
                  off_elevations.empty() ? 0.0 : percentile(off_elevations, 0.5));
    rows += line;
    std::snprintf(line, sizeof line, " %d / %d / %d / %d / %d / %d, %d | %.1f-%.1f |", off_kinds[0],
                  off_kinds[1], off_kinds[2], off_kinds[3], off_kinds[4], off_kinds[5],
                  off_kinds[6], percentile(truth_elevations, 0.05),
                  percentile(truth_elevations, 0.95));
    rows += line;
    auto median = [](const std::vector<double>& values) {
      return values.empty() ? 0.0 : percentile(values, 0.5);
    };
    std::snprintf(line, sizeof line, " %.0f, %.2f | %zu, %.0f, %.2f |\n", median(kept_bins),
                  median(floor_ratios), comb_line_bins.size(), median(comb_line_bins),
                  median(comb_floor_ratios));
    rows += line;
  }
  return rows;
}

std::string format_rows(const std::string& scene, const std::string& tracker,
                        const SceneResult& result) {
  std::string rows;
  char line[256];
  for (const DroneAtArray& cell : result.cells) {
    std::snprintf(line, sizeof line,
                  "| %s | %s | %s | %s | %.3f | %.3f | %.1f %% (%d/%d) | %.1f |\n", scene.c_str(),
                  tracker.c_str(), cell.array_id.c_str(), cell.drone_id.c_str(), cell.median_deg(),
                  cell.p90_deg(), 100.0 * cell.coverage(), cell.found_frames, cell.audible_frames,
                  cell.max_snr_db);
    rows += line;
  }
  std::snprintf(line, sizeof line,
                "| %s | %s | all | stray DOAs | %d of %d | | %.0fx real time |\n", scene.c_str(),
                tracker.c_str(), result.stray_doas, result.doas,
                result.seconds_processed / std::max(result.seconds_cpu, 1e-9));
  rows += line;
  return rows;
}

}  // namespace dronetrack::doa::testing
