#pragma once
// What each source emits, sampled at twice the output rate on an absolute grid (sample i at
// t = i / rate_hz), band-limited to 0.4 x the output rate so the propagation step can evaluate it
// at any emission time with a short windowed-sinc kernel (kernel.hpp). Values are sound pressure
// at 1 m in full-scale units. The samples depend only on (scenario seed, source index, i): any
// time range gives the same values, so every array hears the same source.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sim/scenario.hpp"

namespace dronetrack::sim {

struct SourceBuffer {
  std::int64_t first_index = 0;  // absolute index of samples[0]
  double rate_hz = 96000.0;
  std::vector<float> samples;
  // Position of time t in samples[] units.
  double position(double t_s) const { return t_s * rate_hz - static_cast<double>(first_index); }
};

// Samples covering emission times [begin_s, end_s] plus the interpolation kernel's reach.
SourceBuffer synthesise_source(const Scenario& scenario, std::size_t source_index, double begin_s,
                               double end_s);

// RMS amplitude in full-scale units of `level_db_spl`.
double full_scale_rms(double level_db_spl, double full_scale_db_spl);

}  // namespace dronetrack::sim
