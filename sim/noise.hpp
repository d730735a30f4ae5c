#pragma once
// Noise at the microphones. Each kind is white noise through a fixed filter, so its in-band power
// (what an SNR refers to) follows from the filter's response exactly, without measuring it.
//  - sensor: white, independent per mic.
//  - wind: 2nd-order low-pass (corner ~40 Hz) with slow gusts (amplitude modulation), independent
//    per mic: turbulence at each windscreen is local.
//  - ambient (diffuse): a field from all directions is coherent between nearby mics at low
//    frequency (coherence sinc(2 pi f d / c) ~ 1 below c / (2 d)) and incoherent above. Modelled
//    per array as one common low-passed component plus an independent high-passed one per mic,
//    with power-complementary Butterworth filters, then a gentle -6 dB/octave tilt above 500 Hz.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "doa/doa_params.hpp"

namespace dronetrack::sim {

struct Biquad {
  double b0 = 1, b1 = 0, b2 = 0, a1 = 0, a2 = 0;
  double z1 = 0, z2 = 0;
  double process(double x) {
    const double y = b0 * x + z1;
    z1 = b1 * x - a1 * y + z2;
    z2 = b2 * x - a2 * y;
    return y;
  }
  double power_gain(double frequency_hz, double sample_rate_hz) const;
  static Biquad butterworth_lowpass(double corner_hz, double sample_rate_hz);
  static Biquad butterworth_highpass(double corner_hz, double sample_rate_hz);
  static Biquad one_pole_lowpass(double corner_hz, double sample_rate_hz);
};

enum class NoiseKind { sensor, wind, ambient };

struct NoiseShape {
  NoiseKind kind = NoiseKind::sensor;
  double sample_rate_hz = 48000.0;
  double wind_corner_hz = 40.0;
  double wind_gust_depth = 0.5;
  double ambient_coherent_below_hz = 200.0;

  // Power of the unit-RMS noise that falls in the bands (fraction of 1).
  double inband_fraction(const std::vector<doa::FrequencyBand>& bands) const;
};

// Adds `rms` x unit-RMS noise of `shape` to the channels of an interleaved buffer. Streams come
// from (seed, array_index, channel), so arrays and mics are independent and reproducible.
void add_noise(const NoiseShape& shape, double rms, std::uint64_t seed, std::size_t array_index,
               std::size_t channels, std::size_t frames, float* interleaved);

// Mean in-band power over the channels (Welch, Hann, 8192-point frames).
double measure_inband_power(const float* interleaved, std::size_t channels, std::size_t frames,
                            double sample_rate_hz, const std::vector<doa::FrequencyBand>& bands);

}  // namespace dronetrack::sim
