#include "doa/source_bin_mask.hpp"

#include <algorithm>
#include <array>
#include <complex>

namespace dronetrack::doa {

// Needs no scratch: the scores are summed bin by bin.
SourceBinMask::SourceBinMask(const GccPhat& /*gcc*/, double threshold) : threshold_(threshold) {}

int SourceBinMask::drop(GccPhat& gcc, std::span<const PairTdoa> tdoas) {
  // Pairs inner, bins outer: one rotation e^{j w_k tau_p} per pair advanced bin by bin, the
  // pairs' recurrences independent of each other (no chain of dependent multiplies per bin).
  std::array<int, kMaxPairs> used{};
  int pairs_used = 0;
  for (int p = 0; p < gcc.pair_count() && p < kMaxPairs; ++p)
    if (tdoas[static_cast<std::size_t>(p)].variance_s2 > 0.0)
      used[static_cast<std::size_t>(pairs_used++)] = p;
  if (pairs_used == 0) return 0;
  const double bin_omega = gcc.bin_omega_rad_per_s();
  std::array<const std::complex<double>*, kMaxPairs> phasors{};
  std::array<double, kMaxPairs> step_re{}, step_im{}, rotation_re{}, rotation_im{};
  for (int u = 0; u < pairs_used; ++u) {
    const auto slot = static_cast<std::size_t>(u);
    const double tau = tdoas[static_cast<std::size_t>(used[slot])].tdoa_s;
    phasors[slot] = gcc.phasors(used[slot]).data();
    const std::complex<double> step = std::polar(1.0, bin_omega * tau);
    step_re[slot] = step.real();
    step_im[slot] = step.imag();
  }
  const std::span<std::uint8_t> keep = gcc.bin_keep();
  const double threshold = threshold_ * pairs_used;
  int dropped = 0;
  std::size_t index = 0;
  for (const BandRun& run : gcc.band()) {
    for (int u = 0; u < pairs_used; ++u) {
      const auto slot = static_cast<std::size_t>(u);
      const std::complex<double> first = std::polar(
          1.0, bin_omega * run.first_bin * tdoas[static_cast<std::size_t>(used[slot])].tdoa_s);
      rotation_re[slot] = first.real();
      rotation_im[slot] = first.imag();
    }
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      double score = 0.0;
      for (int u = 0; u < pairs_used; ++u) {
        const auto slot = static_cast<std::size_t>(u);
        const std::complex<double> w = phasors[slot][index];
        const double a_re = rotation_re[slot];
        const double a_im = rotation_im[slot];
        score += w.real() * a_re - w.imag() * a_im;
        rotation_re[slot] = a_re * step_re[slot] - a_im * step_im[slot];
        rotation_im[slot] = a_re * step_im[slot] + a_im * step_re[slot];
      }
      if (keep[index] != 0 && score >= threshold) {
        keep[index] = 0;
        ++dropped;
      }
    }
  }
  return dropped;
}

}  // namespace dronetrack::doa
