#include "doa/cone_peaks.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace dronetrack::doa {

static_assert(kMaxConePeaks <= kMaxGccPeaks, "the GCC keeps fewer peaks than a DOA carries");

ConePeakHistory::ConePeakHistory(const LsDoaSolver& solver, double hop_s)
    : pair_(solver.cone_pair()),
      cosine_per_second_(solver.rank() == 1 ? solver.cone_cosine_for_tdoa(solver.cone_pair(), 1.0)
                                            : 0.0),
      half_hop_s_(0.5 * hop_s) {
  if (solver.rank() != 1)
    throw std::invalid_argument("cone peaks need a two-mic or collinear array");
}

void ConePeakHistory::record(double time_s, const GccPhat& gcc) {
  Frame& frame = frames_[next_];
  next_ = (next_ + 1) % frames_.size();
  frame.time_s = time_s;
  frame.count = 0;
  const PairCorrelation& correlation = gcc.pair(pair_);
  const int count = std::min(correlation.peak_count, kMaxConePeaks);
  for (int k = 0; k < count; ++k) {
    const GccPeak& peak = correlation.peaks[static_cast<std::size_t>(k)];
    if (!(peak.value > 0.0) || !std::isfinite(peak.lag_s)) continue;
    const auto at = static_cast<std::size_t>(frame.count++);
    frame.angle_rad[at] = std::acos(std::clamp(cosine_per_second_ * peak.lag_s, -1.0, 1.0));
    frame.weight[at] = peak.value;
  }
}

bool ConePeakHistory::fill(double time_s, DoaMeasurement& measurement) const {
  measurement.cone_peak_count = 0;
  for (const Frame& frame : frames_) {
    if (!(std::abs(frame.time_s - time_s) < half_hop_s_)) continue;
    measurement.cone_peak_count = frame.count;
    measurement.cone_peak_angle_rad = frame.angle_rad;
    measurement.cone_peak_weight = frame.weight;
    return frame.count > 0;
  }
  return false;
}

}  // namespace dronetrack::doa
