#pragma once
// With two or more sources in one frame, each source's correlation peak sits on the others'
// sidelobes: the PHAT kernel of a 1.5-3.5 kHz band rings at ~2.5 kHz, so a louder source's lobe
// pulls a weaker source's peak by tens of microseconds on the pairs where their lags are close
// (a degree or more of direction). This refines every source's lag, pair by pair, on the
// correlation minus the other sources' kernels (their peak value x the PHAT kernel at their lag),
// alternating over the sources (SAGE / CLEAN style).
#include <span>

#include "doa/gcc_phat.hpp"
#include "doa/ls_doa_solver.hpp"

namespace dronetrack::doa {

class MultiSourceLagRefiner {
 public:
  // initial_step_s: first spacing of the parabolic search, a small fraction of the band's
  // carrier period (400 us at 2.5 kHz); final_step_s: the precision wanted.
  explicit MultiSourceLagRefiner(double initial_step_s = 20e-6, double final_step_s = 1e-6,
                                 int max_iterations = 6)
      : initial_step_s_(initial_step_s),
        final_step_s_(final_step_s),
        max_iterations_(max_iterations) {}

  // sources[s] points at gcc.pair_count() TDOAs of source s (variance <= 0: pair unused);
  // refined in place. A pair whose residual peak is not positive becomes unused.
  void refine(const GccPhat& gcc, std::span<PairTdoa* const> sources, int passes = 2) const;

 private:
  double residual(const GccPhat& gcc, std::span<PairTdoa* const> sources, int source, int pair,
                  double lag_s) const;
  double initial_step_s_;
  double final_step_s_;
  int max_iterations_;
};

}  // namespace dronetrack::doa
