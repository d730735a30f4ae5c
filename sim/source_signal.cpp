#include "sim/source_signal.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <stdexcept>

#include <fftw3.h>
#include <sndfile.h>

#include "sim/kernel.hpp"
#include "sim/random.hpp"

namespace dronetrack::sim {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Stream kinds (random.hpp): each component of each source draws from its own stream.
enum SourceStream : std::uint64_t { kRotorParameters = 1, kBroadband = 2, kTones = 3, kChirps = 4 };

std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  return a / b - ((a % b != 0) && ((a < 0) != (b < 0)) ? 1 : 0);
}

// 0 below `from`, 1 above `to`, raised cosine between.
double ramp(double x, double from, double to) {
  if (x <= from) return 0.0;
  if (x >= to) return 1.0;
  return 0.5 - 0.5 * std::cos(std::numbers::pi * (x - from) / (to - from));
}

// Adds Gaussian noise of RMS `rms` whose power spectrum has the shape `power_shape(f)` to
// `buffer`. Spectral synthesis in 50 %-overlapped sine-windowed blocks on the absolute sample
// grid (block b starts at sample b * hop, its spectrum drawn from stream (source, b)), so any
// time range yields the same samples, and the noise is exactly band-limited.
void add_shaped_noise(SourceBuffer& buffer, std::uint64_t seed, std::size_t source_index,
                      const std::function<double(double)>& power_shape, double rms) {
  constexpr int kBlock = 8192;
  constexpr int kHop = kBlock / 2;
  std::vector<double> amplitude(kBlock / 2 + 1, 0.0);
  double total_power = 0.0;
  for (int k = 1; k < kBlock / 2; ++k) {
    const double power = std::max(0.0, power_shape(k * buffer.rate_hz / kBlock));
    amplitude[static_cast<std::size_t>(k)] = std::sqrt(power);
    total_power += power;
  }
  if (total_power <= 0.0) return;
  // c2r of X_k = (a + ib) S_k has variance 4 sum S_k^2 per sample; the sine windows' squares of
  // overlapping blocks sum to one, so the result keeps it.
  const double scale = rms / std::sqrt(4.0 * total_power);
  fftw_complex* spectrum = fftw_alloc_complex(kBlock / 2 + 1);
  double* block = fftw_alloc_real(kBlock);
  fftw_plan plan = fftw_plan_dft_c2r_1d(kBlock, spectrum, block, FFTW_ESTIMATE);
  std::vector<double> window(kBlock);
  for (int n = 0; n < kBlock; ++n)
    window[static_cast<std::size_t>(n)] = std::sin(std::numbers::pi * (n + 0.5) / kBlock);

  const std::int64_t begin = buffer.first_index;
  const std::int64_t end = begin + static_cast<std::int64_t>(buffer.samples.size());
  for (std::int64_t b = floor_div(begin - kBlock, kHop) + 1; b <= floor_div(end - 1, kHop); ++b) {
    Random random(seed,
                  stream_id(kBroadband, source_index, static_cast<std::uint64_t>(b) & 0xffffff));
    for (int k = 0; k <= kBlock / 2; ++k) {
      const double a = amplitude[static_cast<std::size_t>(k)];
      spectrum[k][0] = a * random.fast_normal();
      spectrum[k][1] = a * random.fast_normal();
    }
    fftw_execute(plan);
    const std::int64_t start = b * kHop;
    const std::int64_t from = std::max(start, begin);
    const std::int64_t to = std::min(start + kBlock, end);
    for (std::int64_t i = from; i < to; ++i) {
      const auto n = static_cast<std::size_t>(i - start);
      buffer.samples[static_cast<std::size_t>(i - begin)] +=
          static_cast<float>(scale * window[n] * block[n]);
    }
  }
  fftw_destroy_plan(plan);
  fftw_free(block);
  fftw_free(spectrum);
}

void synthesise_rotor(const Scenario& scenario, std::size_t source_index, double rms,
                      double band_limit_hz, SourceBuffer& buffer) {
  const RotorSignal& rotor = scenario.sources[source_index].rotor;
  Random random(scenario.seed, stream_id(kRotorParameters, source_index));
  // RPM wander: three slow sinusoids, peak deviation rpm_wander; the phase is their exact
  // integral, so the harmonics stay coherent however long the scene.
  struct Wander {
    double period_s, phase_rad;
  };
  Wander wanders[3];
  const double period_factors[3] = {0.63, 1.0, 1.71};
  for (int i = 0; i < 3; ++i) {
    wanders[i].period_s = rotor.wander_period_s * period_factors[i] * random.uniform(0.85, 1.15);
    wanders[i].phase_rad = random.uniform(0.0, kTwoPi);
  }
  const double depth = rotor.rpm_wander / 3.0;
  auto cycles_at = [&](double t_s) {  // integral of f0(t) dt
    double wander_integral = 0.0;
    for (const auto& wander : wanders) {
      wander_integral -=
          wander.period_s / kTwoPi * std::cos(kTwoPi * t_s / wander.period_s + wander.phase_rad);
    }
    return rotor.blade_pass_hz * (t_s + depth * wander_integral);
  };
  // One period of the waveform as a table over the rotor phase.
  const double highest_fundamental_hz = rotor.blade_pass_hz * (1.0 + rotor.rpm_wander);
  constexpr int kTable = 32768;
  std::vector<float> table(kTable + 1, 0.0f);
  std::vector<double> wave(kTable, 0.0);
  double harmonic_power = 0.0;
  for (int k = 1; k <= rotor.harmonics; ++k) {
    const double jitter_db = 2.0 * random.normal();
    const double phase = random.uniform(0.0, kTwoPi);
    if (k * highest_fundamental_hz > band_limit_hz) continue;
    double level_db = rotor.slope_db_per_octave * std::log2(k) + jitter_db;
    if (rotor.rolloff_corner_hz > 0.0 && k * rotor.blade_pass_hz > rotor.rolloff_corner_hz)
      level_db += rotor.rolloff_db_per_octave *
                  std::log2(k * rotor.blade_pass_hz / rotor.rolloff_corner_hz);
    const double amplitude = std::pow(10.0, level_db / 20.0);
    harmonic_power += amplitude * amplitude / 2.0;
    for (int m = 0; m < kTable; ++m) {
      wave[static_cast<std::size_t>(m)] += amplitude * std::cos(kTwoPi * k * m / kTable + phase);
    }
  }
  const double broadband_ratio = std::pow(10.0, rotor.broadband_db / 10.0);
  const double harmonic_scale = rms / std::sqrt(harmonic_power * (1.0 + broadband_ratio));
  for (int m = 0; m < kTable; ++m) {
    table[static_cast<std::size_t>(m)] =
        static_cast<float>(harmonic_scale * wave[static_cast<std::size_t>(m)]);
  }
  table[kTable] = table[0];
  // The rotor phase evaluated exactly every 64 samples (value and derivative f0) and by cubic
  // Hermite in between: the wander is slow, so the error is far below 1e-9 cycles.
  auto frequency_at = [&](double t_s) {
    double wander = 0.0;
    for (const auto& item : wanders) {
      wander += std::sin(kTwoPi * t_s / item.period_s + item.phase_rad);
    }
    return rotor.blade_pass_hz * (1.0 + depth * wander);
  };
  constexpr std::int64_t kStep = 64;
  const double step_s = kStep / buffer.rate_hz;
  // Blocks on the absolute sample grid, so any time range gives identical samples.
  const auto count = static_cast<std::int64_t>(buffer.samples.size());
  for (std::int64_t block = floor_div(buffer.first_index, kStep) * kStep;
       block < buffer.first_index + count; block += kStep) {
    const double t0 = static_cast<double>(block) / buffer.rate_hz;
    const double y0 = cycles_at(t0);
    const double y1 = cycles_at(t0 + step_s);
    const double m0 = frequency_at(t0) * step_s;
    const double m1 = frequency_at(t0 + step_s) * step_s;
    const double base = std::floor(y0);
    const double difference = y1 - y0;
    const double c2 = 3.0 * difference - 2.0 * m0 - m1;
    const double c3 = -2.0 * difference + m0 + m1;
    const std::int64_t from = std::max(block, buffer.first_index);
    const std::int64_t to = std::min(block + kStep, buffer.first_index + count);
    for (std::int64_t i = from; i < to; ++i) {
      const double u = static_cast<double>(i - block) / kStep;
      const double cycles = (y0 - base) + u * (m0 + u * (c2 + u * c3));
      // cycles >= 0 here, so truncation is the floor.
      const double position =
          (cycles - static_cast<double>(static_cast<long long>(cycles))) * kTable;
      const auto index = static_cast<std::size_t>(position);
      const auto fraction = static_cast<float>(position - static_cast<double>(index));
      buffer.samples[static_cast<std::size_t>(i - buffer.first_index)] +=
          table[index] + fraction * (table[index + 1] - table[index]);
    }
  }
  const double broadband_rms = rms * std::sqrt(broadband_ratio / (1.0 + broadband_ratio));
  const double low_hz = rotor.broadband_low_hz;
  const double high_hz = rotor.broadband_high_hz > 0.0
                             ? std::min(rotor.broadband_high_hz, band_limit_hz)
                             : band_limit_hz;
  add_shaped_noise(
      buffer, scenario.seed, source_index,
      [&](double f) {
        return ramp(f, low_hz, low_hz + 60.0) * (1.0 - ramp(f, 0.9 * high_hz, high_hz)) /
               (1.0 + f / 1000.0);
      },
      broadband_rms);
}

void synthesise_tones(const Scenario& scenario, std::size_t source_index, double rms,
                      SourceBuffer& buffer) {
  const TonesSignal& tones = scenario.sources[source_index].tones;
  Random random(scenario.seed, stream_id(kTones, source_index));
  std::vector<double> amplitudes, phases;
  double power = 0.0;
  for (std::size_t i = 0; i < tones.frequencies_hz.size(); ++i) {
    amplitudes.push_back(std::pow(10.0, tones.relative_db[i] / 20.0));
    phases.push_back(random.uniform(0.0, kTwoPi));
    power += amplitudes.back() * amplitudes.back() / 2.0;
  }
  const double scale = rms / std::sqrt(power);
  for (std::size_t i = 0; i < buffer.samples.size(); ++i) {
    const double t_s =
        static_cast<double>(buffer.first_index + static_cast<std::int64_t>(i)) / buffer.rate_hz;
    double value = 0.0;
    for (std::size_t k = 0; k < amplitudes.size(); ++k) {
      // Reduce the phase in cycles first: t * f reaches 1e6 cycles in long scenes.
      const double cycles = t_s * tones.frequencies_hz[k];
      value += amplitudes[k] * std::cos(kTwoPi * (cycles - std::floor(cycles)) + phases[k]);
    }
    buffer.samples[i] += static_cast<float>(scale * value);
  }
}

// Chirps: chirp k starts at the k-th point of a Poisson process from t = 0 (intervals drawn from
// stream (source, k)), so any time range yields the same samples. Each is a linear sweep between
// two frequencies in [low, high] under a Hann envelope; the level is the RMS while chirping.
void synthesise_chirps(const Scenario& scenario, std::size_t source_index, double rms,
                       SourceBuffer& buffer) {
  const ChirpsSignal& chirps = scenario.sources[source_index].chirps;
  const double amplitude = rms * std::sqrt(2.0) / std::sqrt(0.375);  // Hann^2 mean is 3/8
  const double end_s =
      static_cast<double>(buffer.first_index + static_cast<std::int64_t>(buffer.samples.size())) /
      buffer.rate_hz;
  const double begin_s = static_cast<double>(buffer.first_index) / buffer.rate_hz;
  double start_s = 0.0;
  for (std::uint64_t k = 0; start_s < end_s; ++k) {
    Random random(scenario.seed, stream_id(kChirps, source_index, k & 0xffffff));
    start_s += -chirps.mean_interval_s * std::log(1.0 - random.uniform(0.0, 0.999999));
    const double duration_s = random.uniform(chirps.min_duration_s, chirps.max_duration_s);
    const double from_hz = random.uniform(chirps.low_hz, chirps.high_hz);
    const double to_hz = random.uniform(chirps.low_hz, chirps.high_hz);
    const double phase = random.uniform(0.0, kTwoPi);
    if (start_s + duration_s < begin_s || start_s >= end_s) continue;
    const auto first = std::max<std::int64_t>(
        buffer.first_index, static_cast<std::int64_t>(std::ceil(start_s * buffer.rate_hz)));
    const auto last = std::min<std::int64_t>(
        buffer.first_index + static_cast<std::int64_t>(buffer.samples.size()) - 1,
        static_cast<std::int64_t>(std::floor((start_s + duration_s) * buffer.rate_hz)));
    const double sweep = (to_hz - from_hz) / duration_s;
    for (std::int64_t i = first; i <= last; ++i) {
      const double u = static_cast<double>(i) / buffer.rate_hz - start_s;
      const double envelope = 0.5 - 0.5 * std::cos(kTwoPi * u / duration_s);
      const double cycles = from_hz * u + 0.5 * sweep * u * u;
      buffer.samples[static_cast<std::size_t>(i - buffer.first_index)] += static_cast<float>(
          amplitude * envelope * std::cos(kTwoPi * (cycles - std::floor(cycles)) + phase));
    }
  }
}

// A recording, looped over [start_s, end_s) with an equal-power cross-fade at the seam, then
// resampled onto the source grid with a 64-tap windowed sinc (pass-band to ~16 kHz).
void synthesise_recording(const Scenario& scenario, std::size_t source_index, double rms,
                          double band_limit_hz, SourceBuffer& buffer) {
  const RecordingSignal& recording = scenario.sources[source_index].recording;
  SF_INFO info{};
  SNDFILE* file = sf_open(recording.file.string().c_str(), SFM_READ, &info);
  if (!file) throw std::runtime_error(recording.file.string() + ": cannot read");
  std::vector<float> interleaved(static_cast<std::size_t>(info.frames) *
                                 static_cast<std::size_t>(info.channels));
  const sf_count_t read = sf_readf_float(file, interleaved.data(), info.frames);
  sf_close(file);
  const double input_rate_hz = info.samplerate;
  const auto start = static_cast<std::int64_t>(std::llround(recording.start_s * input_rate_hz));
  const auto end = std::min<std::int64_t>(
      read, recording.end_s ? std::llround(*recording.end_s * input_rate_hz) : read);
  const std::int64_t span = end - start;
  if (span < 16) throw std::runtime_error(recording.file.string() + ": too short to loop");
  const std::int64_t fade = std::min<std::int64_t>(std::llround(0.1 * input_rate_hz), span / 4);
  const std::int64_t period = span - fade;
  std::vector<float> loop(static_cast<std::size_t>(period));
  auto channel0 = [&](std::int64_t frame) {
    return interleaved[static_cast<std::size_t>(frame) * static_cast<std::size_t>(info.channels)];
  };
  double power = 0.0;
  for (std::int64_t j = 0; j < period; ++j) {
    double value = channel0(start + j);
    if (j < fade) {
      const double weight =
          (static_cast<double>(j) + 0.5) / static_cast<double>(fade) * std::numbers::pi / 2.0;
      value = value * std::sin(weight) + channel0(start + period + j) * std::cos(weight);
    }
    loop[static_cast<std::size_t>(j)] = static_cast<float>(value);
    power += value * value;
  }
  power /= static_cast<double>(period);
  if (power <= 0.0) throw std::runtime_error(recording.file.string() + ": silent");
  const double scale = rms / std::sqrt(power);

  const double cutoff_hz = std::min(0.95 * band_limit_hz, 0.41 * input_rate_hz);
  const InterpolationKernel kernel(32, cutoff_hz / input_rate_hz, 8.5, 512);
  const double ratio = input_rate_hz / buffer.rate_hz;
  const double first_position = static_cast<double>(buffer.first_index) * ratio;
  const auto window_begin =
      static_cast<std::int64_t>(std::floor(first_position)) - kernel.half_taps() - 1;
  const auto window_end =
      static_cast<std::int64_t>(std::ceil(
          (static_cast<double>(buffer.first_index) + static_cast<double>(buffer.samples.size())) *
          ratio)) +
      kernel.half_taps() + 1;
  std::vector<float> window(static_cast<std::size_t>(window_end - window_begin));
  for (std::int64_t j = window_begin; j < window_end; ++j) {
    std::int64_t index = j % period;
    if (index < 0) index += period;
    window[static_cast<std::size_t>(j - window_begin)] = loop[static_cast<std::size_t>(index)];
  }
  for (std::size_t i = 0; i < buffer.samples.size(); ++i) {
    const double position =
        static_cast<double>(buffer.first_index + static_cast<std::int64_t>(i)) * ratio -
        static_cast<double>(window_begin);
    buffer.samples[i] += static_cast<float>(scale) * kernel.at(window.data(), position);
  }
}

}  // namespace

double full_scale_rms(double level_db_spl, double full_scale_db_spl) {
  return std::pow(10.0, (level_db_spl - full_scale_db_spl) / 20.0);
}

SourceBuffer synthesise_source(const Scenario& scenario, std::size_t source_index, double begin_s,
                               double end_s) {
  const SourceSpec& source = scenario.sources[source_index];
  SourceBuffer buffer;
  buffer.rate_hz = 2.0 * scenario.sample_rate_hz;
  const double band_limit_hz = 0.4 * scenario.sample_rate_hz;
  const std::int64_t margin = source_kernel().half_taps() + 4;
  buffer.first_index = static_cast<std::int64_t>(std::floor(begin_s * buffer.rate_hz)) - margin;
  const std::int64_t last = static_cast<std::int64_t>(std::ceil(end_s * buffer.rate_hz)) + margin;
  buffer.samples.assign(static_cast<std::size_t>(last - buffer.first_index + 1), 0.0f);
  const double rms = full_scale_rms(source.level_db_spl, scenario.full_scale_db_spl);
  switch (source.signal_type) {
    case SignalType::rotor:
      synthesise_rotor(scenario, source_index, rms, band_limit_hz, buffer);
      break;
    case SignalType::recording:
      synthesise_recording(scenario, source_index, rms, band_limit_hz, buffer);
      break;
    case SignalType::noise: {
      const NoiseSignal& noise = source.noise;
      const double edge_hz = std::min(50.0, 0.1 * (noise.high_hz - noise.low_hz));
      add_shaped_noise(
          buffer, scenario.seed, source_index,
          [&](double f) {
            return ramp(f, noise.low_hz, noise.low_hz + edge_hz) *
                   (1.0 - ramp(f, noise.high_hz - edge_hz, noise.high_hz));
          },
          rms);
      break;
    }
    case SignalType::tones:
      synthesise_tones(scenario, source_index, rms, buffer);
      break;
    case SignalType::chirps:
      synthesise_chirps(scenario, source_index, rms, buffer);
      break;
  }
  return buffer;
}

}  // namespace dronetrack::sim
