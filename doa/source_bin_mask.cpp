#include "doa/source_bin_mask.hpp"

#include <algorithm>
#include <array>
#include <complex>
#include <cstring>

#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

SourceBinMask::SourceBinMask(const GccPhat& gcc, double threshold) : threshold_(threshold) {
  (void)gcc;
}

int SourceBinMask::drop(GccPhat& gcc, std::span<const PairTdoa> tdoas) {
  // Bins outer, pairs inner: one rotation e^{j w_k tau_p} per pair advanced bin by bin, the
  // pairs' recurrences independent of each other.
  std::array<const std::complex<double>*, kMaxPairs> phasors{};
  std::array<double, kMaxPairs> taus{};
  int pairs_used = 0;
  for (int p = 0; p < gcc.pair_count() && p < kMaxPairs; ++p) {
    const PairTdoa& tdoa = tdoas[static_cast<std::size_t>(p)];
    if (!(tdoa.variance_s2 > 0.0)) continue;
    phasors[static_cast<std::size_t>(pairs_used)] = gcc.phasors(p).data();
    taus[static_cast<std::size_t>(pairs_used++)] = tdoa.tdoa_s;
  }
  if (pairs_used == 0) return 0;
  const std::span<const double> scales = gcc.phasor_scales();
  return simd::drop_owned_bins({gcc.band().data(), gcc.band().size(), gcc.bin_omega_rad_per_s(),
                                phasors.data(), taus.data(), pairs_used,
                                scales.empty() ? nullptr : scales.data(), threshold_ * pairs_used,
                                gcc.bin_keep().data()});
}

}  // namespace dronetrack::doa
