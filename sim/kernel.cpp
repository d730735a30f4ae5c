#include "sim/kernel.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace dronetrack::sim {
namespace {

double bessel_i0(double x) {
  double sum = 1.0;
  double term = 1.0;
  for (int k = 1; k < 60; ++k) {
    term *= (x / (2.0 * k)) * (x / (2.0 * k));
    sum += term;
    if (term < 1e-17 * sum) break;
  }
  return sum;
}

}  // namespace

InterpolationKernel::InterpolationKernel(int half_taps, double cutoff, double beta, int phases)
    : half_taps_(half_taps), taps_(2 * half_taps), phases_(phases) {
  if (half_taps < 2 || half_taps % 2 != 0 || phases < 2) {
    throw std::invalid_argument("InterpolationKernel: half_taps must be even and >= 2");
  }
  table_.resize(static_cast<std::size_t>((phases_ + 1) * taps_));
  const double window_norm = bessel_i0(beta);
  for (int phase = 0; phase <= phases_; ++phase) {
    const double fraction = static_cast<double>(phase) / phases_;
    std::vector<double> row(static_cast<std::size_t>(taps_));
    double sum = 0.0;
    for (int tap = 0; tap < taps_; ++tap) {
      // Tap j = tap - half + 1 weighs sample floor(x) + j at distance fraction - j.
      const double x = fraction - (tap - half_taps_ + 1);
      const double u = x / half_taps_;
      const double window =
          std::abs(u) >= 1.0 ? 0.0 : bessel_i0(beta * std::sqrt(1.0 - u * u)) / window_norm;
      const double argument = 2.0 * cutoff * x;
      const double sinc = std::abs(argument) < 1e-12 ? 1.0
                                                     : std::sin(std::numbers::pi * argument) /
                                                           (std::numbers::pi * argument);
      row[static_cast<std::size_t>(tap)] = 2.0 * cutoff * sinc * window;
      sum += row[static_cast<std::size_t>(tap)];
    }
    for (int tap = 0; tap < taps_; ++tap) {
      table_[static_cast<std::size_t>(phase * taps_ + tap)] =
          static_cast<float>(row[static_cast<std::size_t>(tap)] / sum);
    }
  }
}

const InterpolationKernel& source_kernel() {
  static const InterpolationKernel kernel(6, 0.5, 10.0, 256);
  return kernel;
}

}  // namespace dronetrack::sim
