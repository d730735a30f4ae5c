#include "sim/noise.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>

#include <fftw3.h>

#include "sim/random.hpp"

namespace dronetrack::sim {
namespace {

constexpr double kPi = std::numbers::pi;
enum NoiseStream : std::uint64_t {
  kSensor = 10,
  kWind = 11,
  kGust = 12,
  kCommon = 13,
  kLocal = 14
};

// RBJ cookbook with Q = 1/sqrt(2): the bilinear-transformed Butterworth, whose low- and
// high-pass of one corner are power complementary (|L|^2 + |H|^2 = 1).
Biquad cookbook(double corner_hz, double sample_rate_hz, bool highpass) {
  const double w0 = 2.0 * kPi * corner_hz / sample_rate_hz;
  const double alpha = std::sin(w0) / (2.0 * std::sqrt(0.5));
  const double cosine = std::cos(w0);
  const double a0 = 1.0 + alpha;
  Biquad filter;
  if (highpass) {
    filter.b0 = (1.0 + cosine) / 2.0 / a0;
    filter.b1 = -(1.0 + cosine) / a0;
  } else {
    filter.b0 = (1.0 - cosine) / 2.0 / a0;
    filter.b1 = (1.0 - cosine) / a0;
  }
  filter.b2 = filter.b0;
  filter.a1 = -2.0 * cosine / a0;
  filter.a2 = (1.0 - alpha) / a0;
  return filter;
}

double integrate_power(const NoiseShape& shape, double low_hz, double high_hz) {
  // Midpoint rule on a fine grid: the responses are smooth.
  constexpr int kSteps = 20000;
  const double step = (high_hz - low_hz) / kSteps;
  double sum = 0.0;
  const double fs = shape.sample_rate_hz;
  const Biquad wind = Biquad::butterworth_lowpass(shape.wind_corner_hz, fs);
  const Biquad tilt = Biquad::one_pole_lowpass(500.0, fs);
  for (int i = 0; i < kSteps; ++i) {
    const double f = low_hz + (i + 0.5) * step;
    double gain = 1.0;
    if (shape.kind == NoiseKind::wind) gain = wind.power_gain(f, fs);
    if (shape.kind == NoiseKind::ambient) gain = tilt.power_gain(f, fs);
    sum += gain;
  }
  return sum * step * 2.0 / fs;  // white noise of unit variance has density 2 / fs one-sided
}

}  // namespace

double Biquad::power_gain(double frequency_hz, double sample_rate_hz) const {
  const std::complex<double> z = std::polar(1.0, -2.0 * kPi * frequency_hz / sample_rate_hz);
  const std::complex<double> numerator = b0 + b1 * z + b2 * z * z;
  const std::complex<double> denominator = 1.0 + a1 * z + a2 * z * z;
  return std::norm(numerator / denominator);
}

Biquad Biquad::butterworth_lowpass(double corner_hz, double sample_rate_hz) {
  return cookbook(corner_hz, sample_rate_hz, false);
}
Biquad Biquad::butterworth_highpass(double corner_hz, double sample_rate_hz) {
  return cookbook(corner_hz, sample_rate_hz, true);
}
Biquad Biquad::one_pole_lowpass(double corner_hz, double sample_rate_hz) {
  Biquad filter;
  const double pole = std::exp(-2.0 * kPi * corner_hz / sample_rate_hz);
  filter.b0 = 1.0 - pole;
  filter.a1 = -pole;
  return filter;
}

double NoiseShape::inband_fraction(const std::vector<doa::FrequencyBand>& bands) const {
  const double nyquist = sample_rate_hz / 2.0;
  const double total = integrate_power(*this, 0.0, nyquist);
  double inband = 0.0;
  for (const auto& band : bands) {
    const double low = std::min(band.low_hz, nyquist);
    const double high = std::min(band.high_hz, nyquist);
    if (high > low) inband += integrate_power(*this, low, high);
  }
  return inband / total;
}

void add_noise(const NoiseShape& shape, double rms, std::uint64_t seed, std::size_t array_index,
               std::size_t channels, std::size_t frames, float* interleaved) {
  const double fs = shape.sample_rate_hz;
  if (shape.kind == NoiseKind::sensor) {
    for (std::size_t channel = 0; channel < channels; ++channel) {
      Random random(seed, stream_id(kSensor, array_index, channel));
      const auto scale = static_cast<float>(rms);
      for (std::size_t n = 0; n < frames; ++n) {
        interleaved[n * channels + channel] += scale * random.fast_normal();
      }
    }
    return;
  }
  if (shape.kind == NoiseKind::wind) {
    const Biquad prototype = Biquad::butterworth_lowpass(shape.wind_corner_hz, fs);
    // Unit-variance white through the filter has variance 2/fs * integral |H|^2.
    const double filter_rms = std::sqrt(integrate_power(shape, 0.0, fs / 2.0));
    for (std::size_t channel = 0; channel < channels; ++channel) {
      Random random(seed, stream_id(kWind, array_index, channel));
      Random gust_random(seed, stream_id(kGust, array_index, channel));
      // Gusts: 1 + depth * m(t), m the mean of three slow cosines (periods 1.5-8 s), so
      // mean(g^2) = 1 + depth^2 / 6 exactly.
      double gust_rate[3], gust_phase[3];
      for (int i = 0; i < 3; ++i) {
        gust_rate[i] = 2.0 * kPi / gust_random.uniform(1.5, 8.0) / fs;
        gust_phase[i] = gust_random.uniform(0.0, 2.0 * kPi);
      }
      const double depth = shape.wind_gust_depth;
      const double scale = rms / filter_rms / std::sqrt(1.0 + depth * depth / 6.0);
      Biquad filter = prototype;
      // Let the filter settle before t = 0 so the start has no transient.
      for (int n = 0; n < static_cast<int>(4.0 * fs / shape.wind_corner_hz); ++n) {
        filter.process(random.fast_normal());
      }
      // The envelope is slow: evaluate it every 64 samples and interpolate linearly.
      auto envelope_at = [&](std::size_t n) {
        double gust = 0.0;
        for (int i = 0; i < 3; ++i) {
          gust += std::cos(gust_rate[i] * static_cast<double>(n) + gust_phase[i]);
        }
        return 1.0 + depth * gust / 3.0;
      };
      constexpr std::size_t kEnvelopeStep = 64;
      for (std::size_t block = 0; block < frames; block += kEnvelopeStep) {
        const double envelope0 = envelope_at(block);
        const double slope = (envelope_at(block + kEnvelopeStep) - envelope0) / kEnvelopeStep;
        const std::size_t end = std::min(frames, block + kEnvelopeStep);
        for (std::size_t n = block; n < end; ++n) {
          const double envelope = envelope0 + slope * static_cast<double>(n - block);
          interleaved[n * channels + channel] +=
              static_cast<float>(scale * envelope * filter.process(random.fast_normal()));
        }
      }
    }
    return;
  }
  // Ambient: common low-passed + local high-passed, then the tilt, per mic.
  const double filter_rms = std::sqrt(integrate_power(shape, 0.0, fs / 2.0));
  const double scale = rms / filter_rms;
  std::vector<double> common(frames);
  {
    Random random(seed, stream_id(kCommon, array_index));
    Biquad lowpass = Biquad::butterworth_lowpass(shape.ambient_coherent_below_hz, fs);
    for (int n = 0; n < 4096; ++n) lowpass.process(random.fast_normal());
    for (auto& value : common) value = lowpass.process(random.fast_normal());
  }
  for (std::size_t channel = 0; channel < channels; ++channel) {
    Random random(seed, stream_id(kLocal, array_index, channel));
    Biquad highpass = Biquad::butterworth_highpass(shape.ambient_coherent_below_hz, fs);
    Biquad tilt = Biquad::one_pole_lowpass(500.0, fs);
    for (int n = 0; n < 4096; ++n) tilt.process(highpass.process(random.fast_normal()));
    for (std::size_t n = 0; n < frames; ++n) {
      const double value = tilt.process(common[n] + highpass.process(random.fast_normal()));
      interleaved[n * channels + channel] += static_cast<float>(scale * value);
    }
  }
}

double measure_inband_power(const float* interleaved, std::size_t channels, std::size_t frames,
                            double sample_rate_hz, const std::vector<doa::FrequencyBand>& bands) {
  constexpr int kFrame = 8192;
  if (frames < static_cast<std::size_t>(kFrame) || channels == 0) return 0.0;
  double* input = fftw_alloc_real(kFrame);
  fftw_complex* spectrum = fftw_alloc_complex(kFrame / 2 + 1);
  fftw_plan plan = fftw_plan_dft_r2c_1d(kFrame, input, spectrum, FFTW_ESTIMATE);
  std::vector<double> window(kFrame);
  double window_power = 0.0;
  for (int n = 0; n < kFrame; ++n) {
    window[static_cast<std::size_t>(n)] = 0.5 - 0.5 * std::cos(2.0 * kPi * (n + 0.5) / kFrame);
    window_power += window[static_cast<std::size_t>(n)] * window[static_cast<std::size_t>(n)];
  }
  std::vector<int> in_band(kFrame / 2 + 1, 0);
  for (int k = 1; k < kFrame / 2; ++k) {
    const double f = k * sample_rate_hz / kFrame;
    for (const auto& band : bands) {
      if (f >= band.low_hz && f < band.high_hz) in_band[static_cast<std::size_t>(k)] = 1;
    }
  }
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t channel = 0; channel < channels; ++channel) {
    for (std::size_t start = 0; start + kFrame <= frames; start += kFrame / 2) {
      for (int n = 0; n < kFrame; ++n) {
        input[n] = window[static_cast<std::size_t>(n)] *
                   interleaved[(start + static_cast<std::size_t>(n)) * channels + channel];
      }
      fftw_execute(plan);
      double frame_power = 0.0;
      for (int k = 1; k < kFrame / 2; ++k) {
        if (!in_band[static_cast<std::size_t>(k)]) continue;
        frame_power += spectrum[k][0] * spectrum[k][0] + spectrum[k][1] * spectrum[k][1];
      }
      sum += 2.0 * frame_power / (window_power * kFrame);
      ++count;
    }
  }
  fftw_destroy_plan(plan);
  fftw_free(spectrum);
  fftw_free(input);
  return sum / static_cast<double>(count);
}

}  // namespace dronetrack::sim
