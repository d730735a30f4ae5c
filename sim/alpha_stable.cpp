#include "sim/alpha_stable.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace dronetrack::sim {

double draw_alpha_stable(const AlphaStable& law, Random& random) {
  const double alpha = law.alpha;
  const double beta = law.beta;
  if (!(alpha > 0.0 && alpha <= 2.0)) throw std::invalid_argument("alpha-stable: alpha in (0, 2]");
  if (!(beta >= -1.0 && beta <= 1.0)) throw std::invalid_argument("alpha-stable: beta in [-1, 1]");
  if (!(law.scale > 0.0)) throw std::invalid_argument("alpha-stable: scale must be > 0");
  constexpr double kHalfPi = 0.5 * std::numbers::pi;
  // V uniform on (-pi/2, pi/2), W exponential of mean 1; both kept off their end points, where
  // the formulas divide by zero.
  double v = 0.0;
  do {
    v = std::numbers::pi * (random.uniform() - 0.5);
  } while (std::abs(v) >= kHalfPi);
  const double exponential = std::max(-std::log(1.0 - random.uniform()), 1e-300);
  double standard = 0.0;
  if (std::abs(alpha - 1.0) > 1e-12) {
    const double tan_term = beta * std::tan(kHalfPi * alpha);
    const double shift = std::atan(tan_term) / alpha;
    const double stretch = std::pow(1.0 + tan_term * tan_term, 1.0 / (2.0 * alpha));
    standard = stretch * std::sin(alpha * (v + shift)) / std::pow(std::cos(v), 1.0 / alpha) *
               std::pow(std::cos(v - alpha * (v + shift)) / exponential, (1.0 - alpha) / alpha);
    return law.scale * standard + law.location;
  }
  const double tilted = kHalfPi + beta * v;
  standard =
      (tilted * std::tan(v) - beta * std::log(kHalfPi * exponential * std::cos(v) / tilted)) /
      kHalfPi;
  return law.scale * standard + beta * law.scale * std::log(law.scale) / kHalfPi + law.location;
}

double draw_impulsive_mixture(double impulsive_share, double gaussian_std, const AlphaStable& law,
                              Random& random) {
  if (random.uniform() < impulsive_share) return draw_alpha_stable(law, random);
  return gaussian_std * random.normal();
}

}  // namespace dronetrack::sim
