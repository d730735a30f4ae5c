#pragma once
// Per-pair TDOA over time (SPEC 4.3), one interface, chosen by DoaParams::tdoa_tracker:
//   per_frame         : this frame's highest GCC peak.
//   bayesian_grid     : seeds 000/003. P_t(tau) ~ L_t(tau) * (N(0, s_m^2) * P_{t-1})(tau) on the
//                       correlation's lag grid, L_t = max(R, 0)^sharpness + floor; the TDOA is
//                       the MAP, refined on this frame's continuous correlation.
//   multi_peak        : seed 004. Same grid filter, but the likelihood is built from the top K
//                       correlation peaks only (a Gaussian bump at each, height ~ peak value).
//   robust_regression : seed 002. Weighted quadratic fit of the per-frame TDOAs over a sliding
//                       window; points beyond a multiple of the MAD get zero weight. Not made by
//                       make_tdoa_estimator: it runs per source (TdoaRegression in SourceTracks)
//                       on the per-frame TDOAs of each source the frame found.
// The diffusion s_m comes from the largest plausible angular rate of the source.
#include <memory>
#include <span>
#include <vector>

#include <Eigen/Core>

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
  // The frames overlap, so their TDOA errors are correlated: the regression's variance, which
  // treats its points as independent, is multiplied by this
  // (MultichannelFft::overlap_variance_factor).
  double frame_overlap_variance_factor = 1.0;
};

class TdoaEstimator {
 public:
  virtual ~TdoaEstimator() = default;
  // One frame. `signal_present` false (gate closed): predict only, every output pair unused.
  // `out` has one entry per pair of `gcc`.
  virtual void update(double time_s, const GccPhat& gcc, bool signal_present,
                      std::span<PairTdoa> out) = 0;
};

// Seed 002's robust regression of one source's TDOAs, pair by pair: a weighted quadratic in time
// over the last `regression_window_frames` points, started from the median, points beyond
// `regression_mad_gate` x MAD given zero weight, evaluated `regression_delay_frames` hops back.
// Fed per-frame TDOAs of one source (from the GCC peaks, or from one SRP source's lags).
class TdoaRegression {
 public:
  TdoaRegression(int pair_count, const TdoaTrackerSettings& settings);
  // Appends one frame's point for a pair (a pair with variance <= 0 is absent this frame).
  void add(int pair, double time_s, const PairTdoa& tdoa);
  // The fit for time now_s - output_delay_s(); unused (variance 0) unless the window has >= 5
  // fresh points and the frame at that time had a point. With no delay, `current` is the
  // fallback while the window fills.
  PairTdoa estimate(int pair, double now_s, const PairTdoa& current);
  void clear();
  double output_delay_s() const { return delay_s_; }

 private:
  struct Point {
    double time_s = 0.0;
    double tdoa_s = 0.0;
    double variance_s2 = 0.0;
    double peak_value = 0.0;
    double inverse_variance = 0.0;  // the fit's weight, 1 / variance_s2
    double sigma_s = 0.0;           // sqrt(variance_s2), the residual gate's floor
  };
  struct History {
    std::vector<Point> points;
    std::size_t next = 0;
    std::size_t count = 0;
  };
  bool fresh(const History& history, std::size_t i, double now_s) const;
  bool weighted_fit(const History& history, double now_s, Eigen::Vector3d& coefficients,
                    Eigen::Matrix3d& covariance) const;
  void gate_residuals(const History& history);

  TdoaTrackerSettings settings_;
  double delay_s_ = 0.0;
  double max_age_s_ = 0.0;
  std::size_t window_;
  std::vector<History> histories_;
  std::vector<double> residuals_;
  std::vector<double> sorted_;
  std::vector<double> weights_;
};

std::unique_ptr<TdoaEstimator> make_tdoa_estimator(TdoaTracker kind, const GccPhat& gcc,
                                                   const TdoaTrackerSettings& settings);
const char* tdoa_tracker_name(TdoaTracker kind);

}  // namespace dronetrack::doa
