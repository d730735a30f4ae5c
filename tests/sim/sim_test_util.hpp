#pragma once
// Helpers shared by the simulator tests: small scenes built in memory, band-limited delay
// estimation (the cross-correlation evaluated exactly between samples), in-band power.
#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <vector>

#include <fftw3.h>
#include <nlohmann/json.hpp>

#include "sim/render.hpp"
#include "sim/scenario.hpp"

namespace dronetrack::sim::test {

inline nlohmann::json tetrahedron() {
  return {
      {0, 0, 0.5}, {0.4714, 0, -0.1667}, {-0.2357, 0.4082, -0.1667}, {-0.2357, -0.4082, -0.1667}};
}

inline nlohmann::json one_array_site() {
  return {{"speed_of_sound_mps", 343.0},
          {"arrays",
           {{{"id", "A1"},
             {"position_m", {0.0, 0.0, 1.5}},
             {"yaw_deg", 30.0},
             {"mics_m", tetrahedron()}}}}};
}

// A scene with one source and no noise unless the caller adds some.
inline nlohmann::json scene(const nlohmann::json& source, double duration_s = 2.0) {
  return {{"seed", 11},
          {"sample_rate_hz", 48000},
          {"duration_s", duration_s},
          {"site", one_array_site()},
          {"sources", {source}}};
}

inline std::vector<double> channel(const RenderedArray& array, std::size_t index,
                                   std::size_t begin = 0, std::size_t end = 0) {
  if (end == 0) end = array.frames();
  std::vector<double> out;
  for (std::size_t n = begin; n < end; ++n)
    out.push_back(array.samples[n * array.channels + index]);
  return out;
}

// Spectrum of a zero-padded signal (length 2N rounded to a power of two).
inline std::vector<std::complex<double>> spectrum(const std::vector<double>& x, std::size_t size) {
  std::vector<double> input(size, 0.0);
  std::copy(x.begin(), x.end(), input.begin());
  std::vector<std::complex<double>> out(size / 2 + 1);
  fftw_plan plan = fftw_plan_dft_r2c_1d(static_cast<int>(size), input.data(),
                                        reinterpret_cast<fftw_complex*>(out.data()), FFTW_ESTIMATE);
  fftw_execute(plan);
  fftw_destroy_plan(plan);
  return out;
}

// Lag (in samples, fractional) maximising the cross-correlation R(tau) = sum_t a(t + tau) b(t),
// searched within |tau - near| <= range. R is band-limited, so it is evaluated exactly between
// samples from the cross-spectrum (a sum over bins), and refined by Newton on R'(tau) = 0.
inline double correlation_peak_lag(const std::vector<double>& a, const std::vector<double>& b,
                                   double near, double range, double low_hz = 0.0,
                                   double high_hz = 1e9, double sample_rate_hz = 48000.0) {
  std::size_t size = 1;
  while (size < 2 * a.size()) size *= 2;
  const auto spectrum_a = spectrum(a, size);
  const auto spectrum_b = spectrum(b, size);
  std::vector<std::complex<double>> cross(spectrum_a.size());
  for (std::size_t k = 1; k + 1 < cross.size(); ++k) {
    const double f = static_cast<double>(k) * sample_rate_hz / static_cast<double>(size);
    if (f >= low_hz && f <= high_hz) cross[k] = spectrum_a[k] * std::conj(spectrum_b[k]);
  }
  const double omega = 2.0 * std::numbers::pi / static_cast<double>(size);
  // R(tau) and derivatives: sum_k 2 Re(G_k e^{i w k tau}).
  auto evaluate = [&](double tau, double& value, double& first, double& second) {
    value = first = second = 0.0;
    for (std::size_t k = 1; k < cross.size(); ++k) {
      if (cross[k] == 0.0) continue;
      const double w = omega * static_cast<double>(k);
      const std::complex<double> term = cross[k] * std::polar(1.0, w * tau);
      value += term.real();
      first += -w * term.imag();
      second += -w * w * term.real();
    }
  };
  double best = near, best_value = -1e300;
  for (double tau = near - range; tau <= near + range; tau += 0.25) {
    double value, first, second;
    evaluate(tau, value, first, second);
    if (value > best_value) {
      best_value = value;
      best = tau;
    }
  }
  for (int iteration = 0; iteration < 20; ++iteration) {
    double value, first, second;
    evaluate(best, value, first, second);
    if (second >= 0.0) break;
    const double step = -first / second;
    best += std::clamp(step, -0.25, 0.25);
    if (std::abs(step) < 1e-9) break;
  }
  return best;
}

// Power of x within [low_hz, high_hz) (Hann-windowed, one-sided).
inline double band_power(const std::vector<double>& x, double low_hz, double high_hz,
                         double sample_rate_hz = 48000.0) {
  std::vector<double> windowed(x.size());
  double window_power = 0.0;
  for (std::size_t n = 0; n < x.size(); ++n) {
    const double w = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * (n + 0.5) / x.size());
    windowed[n] = w * x[n];
    window_power += w * w;
  }
  const auto bins = spectrum(windowed, x.size());
  double sum = 0.0;
  for (std::size_t k = 1; k + 1 < bins.size(); ++k) {
    const double f = static_cast<double>(k) * sample_rate_hz / static_cast<double>(x.size());
    if (f >= low_hz && f < high_hz) sum += std::norm(bins[k]);
  }
  return 2.0 * sum / (window_power * static_cast<double>(x.size()));
}

// Frequency of the strongest line of x within [low_hz, high_hz] (Hann window, a 0.5 Hz scan,
// then bisection on the exact DTFT to 1e-4 Hz).
inline double strongest_frequency_hz(const std::vector<double>& x, double low_hz, double high_hz,
                                     double sample_rate_hz) {
  auto power_at = [&](double f) {
    std::complex<double> sum = 0.0;
    for (std::size_t n = 0; n < x.size(); ++n) {
      const double w = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * (n + 0.5) / x.size());
      sum += w * x[n] * std::polar(1.0, -2.0 * std::numbers::pi * f * n / sample_rate_hz);
    }
    return std::norm(sum);
  };
  double best_hz = low_hz, best_power = 0.0;
  for (double f = low_hz; f <= high_hz; f += 0.5) {
    const double power = power_at(f);
    if (power > best_power) best_power = power, best_hz = f;
  }
  for (double step = 0.25; step > 1e-4; step /= 2.0) {
    if (power_at(best_hz + step) > best_power)
      best_hz += step, best_power = power_at(best_hz);
    else if (power_at(best_hz - step) > best_power)
      best_hz -= step, best_power = power_at(best_hz);
  }
  return best_hz;
}

}  // namespace dronetrack::sim::test
