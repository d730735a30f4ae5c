#include "tests/doa/scene_eval.hpp"

#include <algorithm>
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

// In-band power of each analysis frame of interleaved audio (same frames as the pipeline).
std::vector<double> frame_powers(const std::vector<float>& samples, std::size_t channels,
                                 double sample_rate_hz, const DoaParams& params) {
  const int frame_length = static_cast<int>(std::lround(params.frame_s * sample_rate_hz));
  const int hop = std::max(1, static_cast<int>(std::lround(params.hop_s * sample_rate_hz)));
  Framer framer(static_cast<int>(channels), frame_length, hop);
  MultichannelFft fft(static_cast<int>(channels), frame_length, fftw_friendly_size(frame_length));
  const std::vector<BandRun> runs = band_runs(params.bands_hz, sample_rate_hz, fft.fft_size());
  std::vector<double> powers;
  const AudioBlockView block{0, static_cast<int>(channels), samples.size() / channels,
                             samples.data()};
  framer.push(block, [&](const FrameView& frame) {
    fft.process(frame);
    double total = 0.0;
    for (int c = 0; c < fft.channels(); ++c)
      for (const BandRun& run : runs)
        for (int k = run.first_bin; k <= run.last_bin; ++k) total += std::norm(fft.spectrum(c)[k]);
    powers.push_back(total);
  });
  return powers;
}

}  // namespace

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
    const std::vector<double> noise_power =
        frame_powers(noise, full.channels, full.sample_rate_hz, params);

    NodePipeline pipeline(geometry, static_cast<int>(a), params, full.sample_rate_hz,
                          scenario.site.speed_of_sound_mps);
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
    std::multimap<int, const DoaMeasurement*> by_frame;
    for (const DoaMeasurement& doa : doas) by_frame.emplace(frame_of(doa.time_s), &doa);

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
      const std::vector<double> drone_power = frame_powers(
          rendered.drone_alone[d][a].samples, full.channels, full.sample_rate_hz, params);
      DroneAtArray cell;
      cell.drone_id = source.id;
      cell.array_id = geometry.id;
      for (std::size_t k = 0; k < drone_power.size() && k < noise_power.size(); ++k) {
        const double snr_db =
            10.0 * std::log10(std::max(drone_power[k], 1e-30) / std::max(noise_power[k], 1e-30));
        cell.max_snr_db = std::max(cell.max_snr_db, snr_db);
        if (snr_db < settings.audible_snr_db) continue;
        ++cell.audible_frames;
        const double time_s =
            (static_cast<double>(k) * hop + 0.5 * (frame_length - 1)) / full.sample_rate_hz;
        const Eigen::Vector3d truth = truth_direction(source, a, time_s);
        double best = 180.0;
        const auto range = by_frame.equal_range(static_cast<int>(k));
        for (auto it = range.first; it != range.second; ++it)
          best = std::min(best, angle_between_deg(it->second->direction, truth));
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
