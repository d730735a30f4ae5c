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

bool SourceBinMask::add_owner(BinOwners& owners, std::span<const PairTdoa> tdoas) const {
  if (owners.sources >= BinOwners::kMaxSources) return false;
  const int first = owners.starts[static_cast<std::size_t>(owners.sources)];
  int terms = first;
  for (std::size_t p = 0; p < tdoas.size() && p < kMaxPairs; ++p) {
    if (!(tdoas[p].variance_s2 > 0.0)) continue;
    if (terms >= BinOwners::kMaxTerms) return false;
    owners.pairs[static_cast<std::size_t>(terms)] = static_cast<int>(p);
    owners.taus_s[static_cast<std::size_t>(terms++)] = tdoas[p].tdoa_s;
  }
  // drop() leaves the mask alone for a source without a measured pair: no terms, no source.
  if (terms == first) return true;
  owners.thresholds[static_cast<std::size_t>(owners.sources)] = threshold_ * (terms - first);
  owners.starts[static_cast<std::size_t>(++owners.sources)] = terms;
  return true;
}

}  // namespace dronetrack::doa
