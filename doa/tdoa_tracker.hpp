#pragma once
// Per-pair TDOA over time (SPEC 4.3), one interface, chosen by DoaParams::tdoa_tracker:
//   per_frame         : this frame's highest GCC peak.
//   bayesian_grid     : seeds 000/003. P_t(tau) ~ L_t(tau) * (N(0, s_m^2) * P_{t-1})(tau) on the
//                       correlation's lag grid, L_t = max(R, 0)^sharpness + floor; the TDOA is
//                       the MAP, refined on this frame's continuous correlation.
//   multi_peak        : seed 004. Same grid filter, but the likelihood is built from the top K
//                       correlation peaks only (a Gaussian bump at each, height ~ peak value).
//   robust_regression : seed 002. Weighted quadratic fit of the per-frame TDOAs over a sliding
//                       window; points beyond a multiple of the MAD get zero weight.
// The diffusion s_m comes from the largest plausible angular rate of the source.
#include <memory>
#include <span>

#include "doa/doa_params.hpp"
#include "doa/gcc_phat.hpp"
#include "doa/ls_doa_solver.hpp"

namespace dronetrack::doa {

struct TdoaTrackerSettings {
  double hop_s = 0.05;
  double max_angular_rate_dps = 90.0;
  double likelihood_sharpness = 4.0;
  double likelihood_floor = 0.02;
  int multi_peak_count = 4;
  int regression_window_frames = 9;
  // robust_regression evaluates its fit this many frames back (the window's centre when
  // (window - 1) / 2): a smoothed TDOA for an earlier frame instead of an extrapolated one for
  // the newest. The DOA then carries that earlier frame's time (output_delay_s()).
  int regression_delay_frames = 0;
  double regression_mad_gate = 3.0;
};

class TdoaEstimator {
 public:
  virtual ~TdoaEstimator() = default;
  // One frame. `signal_present` false (gate closed): predict only, every output pair unused.
  // `out` has one entry per pair of `gcc`.
  virtual void update(double time_s, const GccPhat& gcc, bool signal_present,
                      std::span<PairTdoa> out) = 0;
  // How far before the frame's own time the estimates refer to (their DOA's time offset).
  virtual double output_delay_s() const { return 0.0; }
};

std::unique_ptr<TdoaEstimator> make_tdoa_estimator(TdoaTracker kind, const GccPhat& gcc,
                                                   const TdoaTrackerSettings& settings);
const char* tdoa_tracker_name(TdoaTracker kind);

}  // namespace dronetrack::doa
