#pragma once
// Alpha-stable random numbers S(alpha, beta, c, mu) (Samorodnitsky-Taqqu's parameterisation, the
// one seed 001 states: characteristic function exp(-c^a |t|^a (1 - i b sign(t) tan(pi a / 2)))
// + i mu t) for alpha != 1), drawn by the Chambers-Mallows-Stuck method (Weron 1996 for the
// corrected alpha = 1 case). alpha = 2 is a Gaussian of variance 2c^2, alpha = 1 with beta = 0 a
// Cauchy of scale c, alpha = 1/2 with beta = 1 a Levy of scale c: tests/sim/alpha_stable_test.cpp
// checks the draws against those closed-form quantiles.
//
// Impulsive noise of the kind a reflection, a wind burst or a captured second source puts on an
// acoustic DOA: heavy tails (no variance for alpha < 2), and skewed when beta != 0.
#include "sim/random.hpp"

namespace dronetrack::sim {

struct AlphaStable {
  double alpha = 1.8;     // stability, (0, 2]: 2 is Gaussian, smaller is heavier-tailed
  double beta = 0.0;      // skewness, [-1, 1]
  double scale = 1.0;     // c > 0
  double location = 0.0;  // mu
};

// One draw. Throws std::invalid_argument for parameters outside the ranges above.
double draw_alpha_stable(const AlphaStable& law, Random& random);

// The mixture seed 001 adds to process and measurement (its eq. 3): with probability
// `impulsive_share` a draw from `law`, otherwise a zero-mean Gaussian of `gaussian_std`.
double draw_impulsive_mixture(double impulsive_share, double gaussian_std, const AlphaStable& law,
                              Random& random);

}  // namespace dronetrack::sim
