// Per-frame cost of the array node DSP for a 4-mic 48 kHz tetrahedron at default DoaParams:
//   BM_FftCrossSpectrumKernel: Hann window + r2c FFT of every channel + X_i X_j* of every pair
//                              over the band bins (the irreducible work of any GCC method);
//   BM_NodePipeline:           NodePipeline::process of one hop of interleaved audio (one frame:
//                              framing, FFTs, GCC-PHAT, gate, tracker, LS DOA, SRP-PHAT, ground
//                              echo), on a scene with a source in view and its ground reflection
//                              so every stage runs.
// After the runs it prints the real-time factor per core (hop duration / frame cost) and the
// ratio pipeline / kernel from the same run.
// --simd-target=NAME (AVX3 or AVX512, AVX2, SSE4, NEON, EMU128, ...) forces the kernels' vector
// code (Highway's dispatch) before any benchmark runs; the run ends with the target taken and how
// many kernel calls it served (counts: proof of the path taken, also under emulation). A target
// of two lanes or fewer also keeps FFTW off its AVX codelets, as on a CPU without AVX (the
// kernel and the pipeline's FFTs alike; bench/fftw_codelets.hpp); --fftw-follows-target=0 leaves
// FFTW on what the CPU has (the figures before session 20).
#include <benchmark/benchmark.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/fftw_codelets.hpp"
#include "doa/acoustic_features.hpp"
#include "doa/array_health.hpp"
#include "doa/channel_health.hpp"
#include "doa/gcc_phat.hpp"
#include "doa/node_pipeline.hpp"
#include "doa/simd/dispatch.hpp"
#include "doa/source_bin_mask.hpp"
#include "doa/spectral_frame.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace {

using namespace dronetrack::doa;
constexpr double kRate = 48000.0;
constexpr double kSeconds = 12.0;

// A source in view at 25 deg elevation; with `ground`, also its reflection off the ground under
// the array (coefficient 0.5: the far-field image, mirrored direction, later by
// 2 h sin(elevation) / c at the centre), so that the ground-echo removal runs as in the field.
// With `rotor`, also a rotor's harmonic comb (150 Hz lines, as loud) from another direction, so
// that a frame has two sources and each re-measure looks for its own comb (doa.own_comb_bins,
// stage 7c): band noise alone has no comb and that path never runs. With `generator`, also a
// static broadband source below the horizon (a generator on the ground, ~6 dB over the source in
// every band bin), so that the static null learns it (after static_null_learn_s) and the
// cancellation (stage 3c) projects it out of the bins the null drops: the source under it keeps
// a tenth or more of each bin's power, so most band bins are cancelled and kept.
testing::Recording make_scene(bool ground, bool rotor, bool generator = false) {
  const ArrayGeometry geometry = testing::tetrahedron(30.0);
  const auto frames = static_cast<std::size_t>(kSeconds * kRate);
  testing::Recording out = testing::silent_recording(4, frames);
  const testing::BandNoise source(static_cast<int>(frames), kRate, 500.0, 6000.0, 1);
  const Eigen::Vector3d direction = direction_from_azel_deg(40.0, 25.0);
  testing::add_source(out, geometry, direction, source, 0.05);
  if (ground) {
    const Eigen::Vector3d image(direction.x(), direction.y(), -direction.z());
    const double extra_s = 2.0 * geometry.centre_site_m().z() * direction.z() / 343.0;
    const std::vector<double> delays = testing::plane_wave_delays(geometry, image, 343.0);
    for (int mic = 0; mic < 4; ++mic)
      out.add(mic, source.delayed(extra_s + delays[static_cast<std::size_t>(mic)], 0.5 * 0.05));
  }
  if (rotor) {
    const testing::BandNoise comb =
        testing::BandNoise::comb(static_cast<int>(frames), kRate, 150.0, 500.0, 6000.0, 3);
    testing::add_source(out, geometry, direction_from_azel_deg(200.0, 15.0), comb, 0.05);
  }
  if (generator) {
    const testing::BandNoise engine(static_cast<int>(frames), kRate, 100.0, 6000.0, 4);
    testing::add_source(out, geometry, direction_from_azel_deg(-126.0, -10.0), engine, 0.1);
  }
  testing::add_sensor_noise(out, kRate, 100.0, 12000.0, 0.03, 2);
  return out;
}

enum class Scene { ground, no_ground, rotor, generator };
const testing::Recording& scene(Scene kind = Scene::ground) {
  // Each made on first use only: synthesising one takes a while.
  if (kind == Scene::generator) {
    static const testing::Recording with_generator = make_scene(true, false, true);
    return with_generator;
  }
  if (kind == Scene::no_ground) {
    static const testing::Recording without_ground = make_scene(false, false);
    return without_ground;
  }
  if (kind == Scene::rotor) {
    static const testing::Recording with_rotor = make_scene(true, true);
    return with_rotor;
  }
  static const testing::Recording with_ground = make_scene(true, false);
  return with_ground;
}

void BM_FftCrossSpectrumKernel(benchmark::State& state) {
  const DoaParams params;
  const int frame_length = static_cast<int>(params.frame_s * kRate + 0.5);
  const int hop = static_cast<int>(params.hop_s * kRate + 0.5);
  MultichannelFft fft(4, frame_length, fftw_friendly_size(frame_length));
  const std::vector<BandRun> runs = band_runs(params.bands_hz, kRate, fft.fft_size());
  std::vector<double> channels(static_cast<std::size_t>(4 * frame_length));
  std::vector<std::complex<double>> cross(static_cast<std::size_t>(6 * fft.bin_count()));
  const testing::Recording& audio = scene();
  std::size_t start = 0;
  for (auto _ : state) {
    // Same input per frame as the pipeline sees: a deinterleaved frame at a new hop.
    if (start + static_cast<std::size_t>(frame_length) > audio.frames()) start = 0;
    for (int c = 0; c < 4; ++c)
      for (int n = 0; n < frame_length; ++n)
        channels[static_cast<std::size_t>(c * frame_length + n)] =
            audio.interleaved[(start + static_cast<std::size_t>(n)) * 4 +
                              static_cast<std::size_t>(c)];
    const FrameView frame{static_cast<std::int64_t>(start), 4, frame_length, channels.data(), 0, 0};
    fft.process(frame);
    int pair = 0;
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j, ++pair) {
        const std::complex<double>* x_i = fft.spectrum(i);
        const std::complex<double>* x_j = fft.spectrum(j);
        std::complex<double>* out =
            cross.data() + static_cast<std::ptrdiff_t>(pair) * fft.bin_count();
        for (const BandRun& run : runs)
          for (int k = run.first_bin; k <= run.last_bin; ++k) out[k] = x_i[k] * std::conj(x_j[k]);
      }
    }
    benchmark::DoNotOptimize(cross.data());
    benchmark::ClobberMemory();
    start += static_cast<std::size_t>(hop);
  }
  state.counters["hop_s"] = params.hop_s;
}
BENCHMARK(BM_FftCrossSpectrumKernel)->Unit(benchmark::kMicrosecond);

// Arg 0: default DoaParams; 1: max_sources 1 (no SRP-PHAT); 2: also per_frame TDOAs; 3: default
// DoaParams on the scene without the ground reflection (nothing for the echo removal to do);
// 4: default DoaParams without the acoustic features (their cost is /0 minus /4).
// 5: three bands (0.5-1.5, 1.5-3.5, 3.5-6 kHz) with per-band detection (issue 15: a node per
// band); 6: the same bands as one union (per_band_detection false); 7: default DoaParams without
// the static look (its cost is /0 minus /7); 8: default DoaParams on the scene with a rotor
// beside the source (two sources a frame: the own-comb re-measures run); 9: the same without
// own_comb_bins (that path's cost is /8 minus /9); 10: /8 with follow_source_tracks (the followed
// sources and their fringe judgement run); 11: /8 with free_look_lobe_choice (its cost is /11
// minus /8); 12: default DoaParams on the scene with a ground generator beside the source (the
// static null learns it in the untimed warm-up, the cancellation keeps the bins it drops); 13:
// /12 without static_null_cancel (the null's drop alone: the cancellation's cost is /12 minus
// /13).
void BM_NodePipeline(benchmark::State& state) {
  DoaParams params;
  if (state.range(0) == 13) params.static_null_cancel = false;
  if (state.range(0) == 9) params.own_comb_bins = false;
  if (state.range(0) == 10) params.follow_source_tracks = true;
  if (state.range(0) == 11) params.free_look_lobe_choice = true;
  if (state.range(0) == 4) params.acoustic.enabled = false;
  if (state.range(0) == 7) params.static_look.enabled = false;
  if (state.range(0) == 5 || state.range(0) == 6) {
    params.bands_hz = {{500.0, 1500.0}, {1500.0, 3500.0}, {3500.0, 6000.0}};
    params.per_band_detection = state.range(0) == 5;
  }
  if (state.range(0) == 1 || state.range(0) == 2) params.max_sources = 1;
  if (state.range(0) == 2) params.tdoa_tracker = TdoaTracker::per_frame;
  NodePipeline pipeline(testing::tetrahedron(30.0), 0, params, kRate, 343.0);
  const int hop = pipeline.hop_samples();
  const bool generator = state.range(0) >= 12;
  const testing::Recording& audio = generator             ? scene(Scene::generator)
                                    : state.range(0) == 3 ? scene(Scene::no_ground)
                                    : state.range(0) >= 8 ? scene(Scene::rotor)
                                                          : scene();
  std::vector<DoaMeasurement> out;
  out.reserve(1 << 16);
  // Warm up, untimed: fill the first frame; with the generator, also learn it (the null's
  // learning time and the cancellation's first updates), so every timed frame cancels.
  const auto learned_samples =
      static_cast<std::size_t>(generator ? (params.static_null_learn_s + 1.0) * kRate : 0.0);
  std::size_t next = 0;
  std::int64_t published_before = 0;
  std::int64_t frames_before = 0;
  const auto warm_up = [&] {
    next = static_cast<std::size_t>(pipeline.frame_length_samples());
    pipeline.process(audio.view(0, next), out);
    for (; next < learned_samples; next += static_cast<std::size_t>(hop)) {
      AudioBlockView block = audio.view(next, static_cast<std::size_t>(hop));
      block.first_sample = static_cast<std::int64_t>(next);
      pipeline.process(block, out);
    }
    published_before = pipeline.diagnostics().doas_published;
    frames_before = pipeline.diagnostics().frames_processed;
  };
  warm_up();
  for (auto _ : state) {
    if (next + static_cast<std::size_t>(hop) > audio.frames()) {
      state.PauseTiming();
      pipeline = NodePipeline(testing::tetrahedron(30.0), 0, params, kRate, 343.0);
      warm_up();
      state.ResumeTiming();
    }
    AudioBlockView block = audio.view(next, static_cast<std::size_t>(hop));
    block.first_sample = static_cast<std::int64_t>(next);
    pipeline.process(block, out);
    next += static_cast<std::size_t>(hop);
    if (out.size() > (1 << 15)) out.clear();  // keeps capacity: no allocation
  }
  const auto frames = pipeline.diagnostics().frames_processed - frames_before;
  state.counters["doas_per_frame"] =
      frames > 0 ? double(pipeline.diagnostics().doas_published - published_before) / frames : 0.0;
  state.counters["nulled"] = pipeline.diagnostics().static_sources_nulled;
}
BENCHMARK(BM_NodePipeline)
    ->Arg(0)
    ->Arg(1)
    ->Arg(2)
    ->Arg(3)
    ->Arg(4)
    ->Arg(5)
    ->Arg(6)
    ->Arg(7)
    ->Arg(8)
    ->Arg(9)
    ->Arg(10)
    ->Arg(11)
    ->Arg(12)
    ->Arg(13)
    ->Unit(benchmark::kMicrosecond);

// The bench scene's first frame (channel-major, as the Framer gives it) through `fft`.
void transform_first_frame(MultichannelFft& fft) {
  const int frame_length = fft.frame_length();
  std::vector<double> channels(static_cast<std::size_t>(4 * frame_length));
  const testing::Recording& audio = scene();
  for (int c = 0; c < 4; ++c)
    for (int n = 0; n < frame_length; ++n)
      channels[static_cast<std::size_t>(c * frame_length + n)] =
          audio.interleaved[static_cast<std::size_t>(n) * 4 + static_cast<std::size_t>(c)];
  fft.process(FrameView{0, 4, frame_length, channels.data(), 0, 0});
}

// Per-stage costs on one frame of the same scene (for profiling the pipeline; not in the ratio):
// Arg 0: GccPhat::whiten; 1: correlate() with peak refinement; 2: correlate(false), the lag
// grid only; 3: SourceBinMask::drop of the frame's source (after the whitening is restored);
// 4: correlate(false) with that source's bins dropped (the further looks' re-correlation).
void BM_PipelineStage(benchmark::State& state) {
  const DoaParams params;
  const ArrayGeometry geometry = testing::tetrahedron(30.0);
  const int frame_length = static_cast<int>(params.frame_s * kRate + 0.5);
  MultichannelFft fft(4, frame_length, fftw_friendly_size(frame_length));
  const std::vector<MicPairSpec> pairs = testing::all_pairs(geometry);
  GccPhat gcc(fft.fft_size(), frame_length, kRate, params.bands_hz, pairs, params.lag_interpolation,
              params.correlation_oversample);
  SourceBinMask mask(gcc);
  transform_first_frame(fft);
  gcc.whiten(fft);
  gcc.correlate();
  std::vector<PairTdoa> tdoas(pairs.size());
  for (int p = 0; p < gcc.pair_count(); ++p)
    tdoas[static_cast<std::size_t>(p)] = {gcc.pair(p).peak.lag_s, gcc.pair(p).tdoa_variance_s2,
                                          gcc.pair(p).peak.value, gcc.pair(p).coherence};
  const std::vector<std::uint8_t> whitened_mask(gcc.bin_keep().begin(), gcc.bin_keep().end());
  const auto stage = state.range(0);
  if (stage == 4) mask.drop(gcc, tdoas);
  for (auto _ : state) {
    if (stage == 0) gcc.whiten(fft);
    if (stage == 1) gcc.correlate(true);
    if (stage == 2) gcc.correlate(false);
    if (stage == 4) gcc.correlate(false);
    if (stage == 3) {
      state.PauseTiming();
      gcc.cross_power(gcc.units(), whitened_mask);
      state.ResumeTiming();
      benchmark::DoNotOptimize(mask.drop(gcc, tdoas));
    }
    benchmark::ClobberMemory();
  }
  if (stage == 3) {
    gcc.correlate(false);
    state.counters["kept_share"] = double(gcc.kept_bin_count()) / gcc.band_bin_count();
  }
}
BENCHMARK(BM_PipelineStage)->DenseRange(0, 4)->Unit(benchmark::kMicrosecond);

// The acoustic features of one source on one frame of the same scene (what the pipeline pays
// every analysis_every_frames frames): bins steered and assigned, comb detector, history.
void BM_AcousticFeatures(benchmark::State& state) {
  const DoaParams params;
  const ArrayGeometry geometry = testing::tetrahedron(30.0);
  const int frame_length = static_cast<int>(params.frame_s * kRate + 0.5);
  MultichannelFft fft(4, frame_length, fftw_friendly_size(frame_length));
  transform_first_frame(fft);
  AcousticFeatureExtractor extractor(geometry, fft.fft_size(), kRate, 343.0, params.hop_s,
                                     params.acoustic);
  const std::array<Eigen::Vector3d, 1> directions{direction_from_azel_deg(40.0, 25.0)};
  const std::array<int, 1> slots{0};
  const std::array<std::uint32_t, 1> generations{1};
  for (auto _ : state) {
    extractor.analyse(fft, directions, slots, generations);
    benchmark::DoNotOptimize(extractor.features(0));
  }
}
BENCHMARK(BM_AcousticFeatures)->Unit(benchmark::kMicrosecond);

// The framer alone: one hop of interleaved audio in (deinterleaving, level, clipping and
// NaN checks), frames out to a callback that does nothing.
void BM_Framer(benchmark::State& state) {
  const DoaParams params;
  const int frame_length = static_cast<int>(params.frame_s * kRate + 0.5);
  const int hop = static_cast<int>(params.hop_s * kRate + 0.5);
  Framer framer(4, frame_length, hop);
  const testing::Recording& audio = scene();
  std::size_t next = 0;
  std::int64_t frames = 0;
  for (auto _ : state) {
    if (next + static_cast<std::size_t>(hop) > audio.frames()) next = 0;
    AudioBlockView block = audio.view(next, static_cast<std::size_t>(hop));
    block.first_sample = static_cast<std::int64_t>(next);
    framer.push(block, [&](const FrameView& frame) { frames += frame.length > 0 ? 1 : 0; });
    next += static_cast<std::size_t>(hop);
  }
  benchmark::DoNotOptimize(frames);
}
BENCHMARK(BM_Framer)->Unit(benchmark::kMicrosecond);

// The audio health as the node counts it: the framer's pass over one hop of interleaved audio
// with ChannelHealth::observe() taking each run's per-channel sums (its cost is this minus
// BM_Framer), the stretch judged once a second. Arg 1: one channel all NaN and one clipped hard
// (the sample-by-sample path).
void BM_ChannelHealth(benchmark::State& state) {
  const DoaParams params;
  const int hop = static_cast<int>(params.hop_s * kRate + 0.5);
  static const testing::Recording broken = [] {
    testing::Recording copy = scene();
    for (std::size_t n = 0; n < copy.frames(); ++n) {
      copy.interleaved[n * 4 + 1] = std::numeric_limits<float>::quiet_NaN();
      copy.interleaved[n * 4 + 2] *= 100.0F;
    }
    return copy;
  }();
  const testing::Recording& audio = state.range(0) == 1 ? broken : scene();
  const int frame_length = static_cast<int>(params.frame_s * kRate + 0.5);
  Framer framer(4, frame_length, hop);
  ChannelHealth health(4, kRate);
  std::size_t next = 0;
  std::int64_t frames = 0;
  for (auto _ : state) {
    if (next + static_cast<std::size_t>(hop) > audio.frames()) next = 0;
    AudioBlockView block = audio.view(next, static_cast<std::size_t>(hop));
    block.first_sample = static_cast<std::int64_t>(next);
    health.clear_events();  // as the node does before each block
    framer.push(
        block, [&](const FrameView& frame) { frames += frame.length > 0 ? 1 : 0; }, health);
    next += static_cast<std::size_t>(hop);
  }
  benchmark::DoNotOptimize(frames);
  benchmark::DoNotOptimize(health.non_finite_samples());
}
BENCHMARK(BM_ChannelHealth)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// The array health checks of one frame as NodePipeline runs them: each pair's lag grid read for
// its extremes (the grid of a 0.82 m pair at the default band and oversampling), then observe()
// with a source from a direction that turns 1.5 deg a frame (closure, the delay fit; each
// check's judgement once per 20 frames, amortised). Arg 1: an irregular tetrahedron, whose six
// swaps the swap check tests on every such frame (a regular one's are mirrors: none tested).
void BM_ArrayHealth(benchmark::State& state) {
  const DoaParams params;
  ArrayGeometry geometry = testing::tetrahedron(30.0);
  if (state.range(0) == 1)
    geometry.mics_m = {
        {0.0, 0.0, 0.6}, {0.55, 0.0, -0.1}, {-0.2, 0.45, -0.2}, {-0.3, -0.35, -0.15}};
  ArrayHealth health(geometry, 343.0, params.hop_s);
  const double lag_step_s =
      1.0 / (2.0 * params.bands_hz.back().high_hz * params.correlation_oversample);
  const double max_lag_s = (geometry.mics_m[0] - geometry.mics_m[1]).norm() / 343.0;
  const auto grid_length = static_cast<std::size_t>(2.0 * std::ceil(max_lag_s / lag_step_s) + 1);
  std::vector<double> grid(grid_length);
  for (std::size_t n = 0; n < grid.size(); ++n)
    grid[n] = std::cos(0.3 * static_cast<double>(n)) / (1.0 + 0.05 * static_cast<double>(n));
  const std::vector<double> power = {1e-4, 1.1e-4, 0.9e-4, 1e-4};
  std::vector<PairPeak> pairs(6);
  int frame = 0;
  for (auto _ : state) {
    const double azimuth = 0.026 * frame;
    const Eigen::Vector3d u(std::cos(azimuth) * 0.9, std::sin(azimuth) * 0.9, 0.436);
    int p = 0;
    for (std::size_t i = 0; i < 4; ++i) {
      for (std::size_t j = i + 1; j < 4; ++j, ++p) {
        PairPeak& pair = pairs[static_cast<std::size_t>(p)];
        pair = correlation_extremes(grid);
        pair.tdoa_s = (geometry.mics_m[j] - geometry.mics_m[i]).dot(u.normalized()) / 343.0;
      }
    }
    health.observe(frame * params.hop_s, power, pairs, true, true);
    health.clear_events();
    ++frame;
  }
  benchmark::DoNotOptimize(health.closure_residual_us());
}
BENCHMARK(BM_ArrayHealth)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Records each benchmark's CPU time per iteration so main() can print the ratio: the median
// over repetitions when --benchmark_repetitions is given (the machine is shared: single runs
// are noisy), else the one run.
class RecordingReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      const std::string name = run.run_name.str();
      if (run.run_type == Run::RT_Iteration && run.iterations > 0 && !medians.contains(name))
        seconds[name] = run.GetAdjustedCPUTime() * 1e-6;
      if (run.run_type == Run::RT_Aggregate && run.aggregate_name == "median") {
        seconds[name] = run.GetAdjustedCPUTime() * 1e-6;
        medians[name] = true;
      }
    }
    ConsoleReporter::ReportRuns(runs);
  }
  std::map<std::string, double> seconds;  // CPU seconds per iteration
  std::map<std::string, bool> medians;    // which of them are medians over repetitions
};

}  // namespace

int main(int argc, char** argv) {
  // Our flag out of argv before Google Benchmark sees (and rejects) it.
  constexpr const char* kTargetFlag = "--simd-target=";
  constexpr const char* kFollowFlag = "--fftw-follows-target=";
  bool fftw_follows_target = true;
  int kept = 1;
  for (int a = 1; a < argc; ++a) {
    if (std::strncmp(argv[a], kFollowFlag, std::strlen(kFollowFlag)) == 0) {
      const std::string value = argv[a] + std::strlen(kFollowFlag);
      if (value != "0" && value != "1") {
        std::fprintf(stderr, "doa_bench: %s wants 0 or 1, not '%s'\n", kFollowFlag, value.c_str());
        return 2;
      }
      fftw_follows_target = value == "1";
    } else if (std::strncmp(argv[a], kTargetFlag, std::strlen(kTargetFlag)) == 0) {
      try {
        set_simd_target(argv[a] + std::strlen(kTargetFlag));
      } catch (const std::invalid_argument& error) {
        std::fprintf(stderr, "doa_bench: %s\n", error.what());
        return 2;
      }
    } else {
      argv[kept++] = argv[a];
    }
  }
  argc = kept;
  // Before any plan is made: FFTW chooses its codelets when planning.
  dronetrack::bench::allow_fftw_avx(!fftw_follows_target || simd_double_lanes() > 2);
  benchmark::Initialize(&argc, argv);
  RecordingReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  const auto kernel = reporter.seconds.find("BM_FftCrossSpectrumKernel");
  const auto pipeline = reporter.seconds.find("BM_NodePipeline/0");
  if (kernel != reporter.seconds.end() && pipeline != reporter.seconds.end()) {
    const double hop_s = DoaParams{}.hop_s;
    std::printf("\n4-mic 48 kHz array, default DoaParams (frame %.2f s, hop %.2f s), CPU time%s:\n",
                DoaParams{}.frame_s, hop_s,
                reporter.medians.contains("BM_NodePipeline/0") ? ", median of repetitions" : "");
    std::printf("  FFT + cross-spectrum kernel: %8.1f us/frame, %7.0fx real time per core\n",
                kernel->second * 1e6, hop_s / kernel->second);
    std::printf("  whole node pipeline:         %8.1f us/frame, %7.0fx real time per core\n",
                pipeline->second * 1e6, hop_s / pipeline->second);
    std::printf("  pipeline / kernel:           %8.2f   (a source and its ground reflection)\n",
                pipeline->second / kernel->second);
    const auto no_ground = reporter.seconds.find("BM_NodePipeline/3");
    if (no_ground != reporter.seconds.end())
      std::printf(
          "  pipeline / kernel:           %8.2f   (the same source, no ground reflection)\n",
          no_ground->second / kernel->second);
    for (const auto& [name, label] : {std::pair{"BM_ArrayHealth/0", "array health checks:        "},
                                      {"BM_ArrayHealth/1", "  irregular array (swaps):  "}}) {
      const auto array_health = reporter.seconds.find(name);
      if (array_health != reporter.seconds.end())
        std::printf("  %s %8.2f us/frame, %5.2f %% of the pipeline\n", label,
                    array_health->second * 1e6, 100.0 * array_health->second / pipeline->second);
    }
    const auto no_features = reporter.seconds.find("BM_NodePipeline/4");
    if (no_features != reporter.seconds.end())
      std::printf(
          "  pipeline / kernel:           %8.2f   (without the acoustic features: they add "
          "%.1f us/frame)\n",
          no_features->second / kernel->second, (pipeline->second - no_features->second) * 1e6);
    const auto no_static_look = reporter.seconds.find("BM_NodePipeline/7");
    if (no_static_look != reporter.seconds.end())
      std::printf(
          "  pipeline / kernel:           %8.2f   (without the static look: it adds %.1f "
          "us/frame)\n",
          no_static_look->second / kernel->second,
          (pipeline->second - no_static_look->second) * 1e6);
    // A scene's ratio, then the same scene without one stage and what that stage adds.
    const auto scene_and_stage = [&](const char* with, const char* scene_label, const char* without,
                                     const char* stage_label) {
      const auto found = reporter.seconds.find(with);
      if (found == reporter.seconds.end()) return;
      std::printf("  pipeline / kernel:           %8.2f   (%s)\n", found->second / kernel->second,
                  scene_label);
      const auto other = reporter.seconds.find(without);
      if (other != reporter.seconds.end())
        std::printf("  pipeline / kernel:           %8.2f   (%s %.1f us/frame)\n",
                    other->second / kernel->second, stage_label,
                    (found->second - other->second) * 1e6);
    };
    scene_and_stage("BM_NodePipeline/8", "beside a rotor: two sources a frame", "BM_NodePipeline/9",
                    "the same without own_comb_bins: they add");
    scene_and_stage("BM_NodePipeline/12", "beside a ground generator, cancelled",
                    "BM_NodePipeline/13", "the same, its bins dropped: the cancellation adds");
  }
  const std::string target = simd_target_name();
  std::printf("SIMD target %s (%d doubles per vector): %llu kernel calls on it, %llu on all\n",
              target.c_str(), simd_double_lanes(),
              static_cast<unsigned long long>(simd_dispatch_count(target)),
              static_cast<unsigned long long>(simd_dispatch_count()));
  const DoaParams params;
  const int fft_size = fftw_friendly_size(static_cast<int>(params.frame_s * kRate + 0.5));
  std::printf("FFTW codelets of the frame's r2c (%d points): %s%s\n", fft_size,
              dronetrack::bench::fftw_codelet_set(fft_size).c_str(),
              fftw_follows_target ? "" : " (--fftw-follows-target=0)");
  return 0;
}
