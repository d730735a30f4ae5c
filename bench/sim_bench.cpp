// Synthesis speed of the simulator on one core: a 60 s scene of four tetrahedral arrays (16
// channels at 48 kHz) with two drones, ground reflections and all three noise kinds
// (config/scenarios/perimeter-two-drones.json), rendered in memory (no file writing). Prints
// the real-time factor: seconds of scene per second of CPU time of this (single-threaded) process,
// so other load on a shared machine does not distort it; the wall-clock factor is printed too.
#include <chrono>
#include <cstdio>
#include <ctime>
#include <vector>

#include <benchmark/benchmark.h>

#include "sim/render.hpp"
#include "sim/scenario.hpp"

namespace {

using namespace dronetrack;

sim::Scenario perimeter_scene() {
  std::vector<std::string> warnings;
  return sim::load_scenario(DRONETRACK_SOURCE_DIR "/config/scenarios/perimeter-two-drones.json",
                            warnings);
}

void BM_RenderPerimeter60s(benchmark::State& state) {
  const sim::Scenario scenario = perimeter_scene();
  for (auto _ : state) {
    const auto started = std::chrono::steady_clock::now();
    const std::clock_t cpu_started = std::clock();
    sim::RenderedScene scene = sim::render_scene(scenario);
    const double cpu_s = static_cast<double>(std::clock() - cpu_started) / CLOCKS_PER_SEC;
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    benchmark::DoNotOptimize(scene.arrays.data());
    state.counters["realtime_factor_cpu"] = scenario.duration_s / cpu_s;
    std::printf(
        "sim: %.0f s scene, %zu arrays x %zu channels at %.0f Hz, %zu sources: "
        "%.2f s CPU on one core = %.1fx real time (wall clock %.2f s = %.1fx)\n",
        scenario.duration_s, scene.arrays.size(), scene.arrays.front().channels,
        scenario.sample_rate_hz, scenario.sources.size(), cpu_s, scenario.duration_s / cpu_s,
        wall_s, scenario.duration_s / wall_s);
  }
}
BENCHMARK(BM_RenderPerimeter60s)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
