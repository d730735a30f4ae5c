#include "doa/source_bin_mask.hpp"

#include <algorithm>
#include <complex>

namespace dronetrack::doa {

SourceBinMask::SourceBinMask(const GccPhat& gcc, double threshold)
    : threshold_(threshold), scores_(static_cast<std::size_t>(gcc.band_bin_count()), 0.0) {}

int SourceBinMask::drop(GccPhat& gcc, std::span<const PairTdoa> tdoas) {
  std::fill(scores_.begin(), scores_.end(), 0.0);
  int pairs_used = 0;
  const double bin_omega = gcc.bin_omega_rad_per_s();
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairTdoa& tdoa = tdoas[static_cast<std::size_t>(p)];
    if (!(tdoa.variance_s2 > 0.0)) continue;
    ++pairs_used;
    const std::span<const std::complex<double>> phasors = gcc.phasors(p);
    const std::complex<double> step = std::polar(1.0, bin_omega * tdoa.tdoa_s);
    std::size_t index = 0;
    for (const BandRun& run : gcc.band()) {
      std::complex<double> rotation = std::polar(1.0, bin_omega * run.first_bin * tdoa.tdoa_s);
      for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
        scores_[index] += (phasors[index] * rotation).real();
        rotation *= step;
      }
    }
  }
  if (pairs_used == 0) return 0;
  const std::span<std::uint8_t> keep = gcc.bin_keep();
  const double threshold = threshold_ * pairs_used;
  int dropped = 0;
  for (std::size_t k = 0; k < scores_.size(); ++k) {
    if (keep[k] != 0 && scores_[k] >= threshold) {
      keep[k] = 0;
      ++dropped;
    }
  }
  return dropped;
}

}  // namespace dronetrack::doa
