#include "doa/multi_source_refiner.hpp"

#include <algorithm>
#include <cmath>

namespace dronetrack::doa {

double MultiSourceLagRefiner::residual(const GccPhat& gcc, std::span<PairTdoa* const> sources,
                                       int source, int pair, double lag_s) const {
  double value = gcc.value_at(pair, lag_s);
  for (int other = 0; other < static_cast<int>(sources.size()); ++other) {
    if (other == source) continue;
    const PairTdoa& tdoa = sources[static_cast<std::size_t>(other)][pair];
    if (tdoa.variance_s2 > 0.0) value -= tdoa.peak_value * gcc.phat_kernel(lag_s - tdoa.tdoa_s);
  }
  return value;
}

void MultiSourceLagRefiner::refine(const GccPhat& gcc, std::span<PairTdoa* const> sources,
                                   int passes) const {
  if (sources.size() < 2) return;
  for (int pass = 0; pass < passes; ++pass) {
    for (int s = 0; s < static_cast<int>(sources.size()); ++s) {
      for (int p = 0; p < gcc.pair_count(); ++p) {
        PairTdoa& tdoa = sources[static_cast<std::size_t>(s)][p];
        if (!(tdoa.variance_s2 > 0.0)) continue;
        const double limit_s = gcc.pair_spec(p).max_lag_s + gcc.lag_step_s();
        // Parabolas through three points, stepping uphill while the three do not bracket a
        // maximum, then shrinking the spacing: ~8 evaluations of the continuous correlation.
        double lag = tdoa.tdoa_s;
        double value = residual(gcc, sources, s, p, lag);
        double h = initial_step_s_;
        for (int iteration = 0; iteration < max_iterations_ && h >= final_step_s_; ++iteration) {
          const double below = residual(gcc, sources, s, p, std::max(lag - h, -limit_s));
          const double above = residual(gcc, sources, s, p, std::min(lag + h, limit_s));
          const double curvature = below - 2.0 * value + above;
          double next = lag;
          if (!(curvature < 0.0)) {
            next = lag + (above > below ? h : -h);
          } else {
            const double offset = std::clamp(0.5 * (below - above) / curvature, -1.0, 1.0);
            next = lag + offset * h;
            if (std::abs(offset) < 0.5) h *= 0.25;
          }
          next = std::clamp(next, -limit_s, limit_s);
          const double next_value = residual(gcc, sources, s, p, next);
          if (next_value < value) {
            h *= 0.25;
            continue;
          }
          lag = next;
          value = next_value;
        }
        if (!(value > 0.0)) {
          tdoa = PairTdoa{};
          continue;
        }
        tdoa.tdoa_s = lag;
        tdoa.peak_value = value;
        tdoa.variance_s2 = gcc.tdoa_variance_for_peak(value);
      }
    }
  }
}

}  // namespace dronetrack::doa
