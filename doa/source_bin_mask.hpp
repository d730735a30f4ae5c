#pragma once
// Drops the band bins a found source dominates, so that the next correlation shows what that
// source masked. In a bin one source dominates (W-disjoint orthogonality: two drones' rotor
// harmonics sit at different frequencies), and there its PHAT phasor on every pair is
// e^{-j w tau_p} for that source's TDOAs tau_p. A bin whose phasors agree with a found source
// on average over the pairs (mean of Re(W_p e^{j w tau_p}) >= threshold) is that source's; the
// rest carry the weaker sources and noise. After GccPhat::correlate() the correlations are
// normalised by the bins kept, so a drone 10 dB below a nearer one still gives a clear peak.
#include <complex>
#include <span>
#include <vector>

#include "doa/gcc_phat.hpp"
#include "doa/ls_doa_solver.hpp"

namespace dronetrack::doa {

class SourceBinMask {
 public:
  // threshold: mean agreement over pairs; one dominant source gives ~1, noise ~0 +- 1/sqrt(2P).
  SourceBinMask(const GccPhat& gcc, double threshold = 0.5);

  // Clears, in gcc.bin_keep(), the bins the source with these TDOAs dominates (after
  // GccPhat::whiten(), before correlate()); returns how many it cleared.
  int drop(GccPhat& gcc, std::span<const PairTdoa> tdoas);
  // The same test for a look that drops as it makes its phasors (GccPhat::cross_power_from()):
  // this source's terms appended to `owners`; false (owners unchanged) when they do not fit.
  bool add_owner(BinOwners& owners, std::span<const PairTdoa> tdoas) const;

 private:
  double threshold_;
};

}  // namespace dronetrack::doa
