#pragma once
// A two-mic (or collinear) array's strongest GCC peaks as cone angles, per frame (seed 004's
// multi-peak likelihood, SPEC 4.3: the top K = 4 peaks, not only the largest). Kept for the last
// 64 frames, because a smoothed DOA (robust_regression) is published for a frame some hops back
// and must carry that frame's peaks. Fixed arrays: nothing is allocated per frame.
#include <array>

#include "doa/doa_measurement.hpp"
#include "doa/gcc_phat.hpp"
#include "doa/ls_doa_solver.hpp"

namespace dronetrack::doa {

class ConePeakHistory {
 public:
  // `solver` of a rank-1 geometry (throws std::invalid_argument otherwise); frames are hop_s
  // apart.
  ConePeakHistory(const LsDoaSolver& solver, double hop_s);

  // This frame's peaks of the solver's cone pair, after GccPhat::correlate() with
  // set_peak_count(kMaxConePeaks).
  void record(double time_s, const GccPhat& gcc);
  // measurement.cone_peak_* from the frame at time_s: cone angles in [0, pi], strongest first,
  // with their normalised GCC values as weights. False (count 0) when that frame is not kept.
  bool fill(double time_s, DoaMeasurement& measurement) const;

 private:
  struct Frame {
    double time_s = -1e300;
    int count = 0;
    std::array<double, kMaxConePeaks> angle_rad{};
    std::array<double, kMaxConePeaks> weight{};
  };
  int pair_ = 0;
  double cosine_per_second_ = 0.0;  // cos(cone angle) per second of the pair's TDOA
  double half_hop_s_ = 0.0;
  std::array<Frame, 64> frames_{};  // ring
  std::size_t next_ = 0;
};

}  // namespace dronetrack::doa
