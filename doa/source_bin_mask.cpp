#include "doa/source_bin_mask.hpp"

#include <algorithm>
#include <array>
#include <complex>

namespace dronetrack::doa {

SourceBinMask::SourceBinMask(const GccPhat& gcc, double threshold)
    : threshold_(threshold), zeros_(static_cast<std::size_t>(gcc.band_bin_count())) {}

int SourceBinMask::drop(GccPhat& gcc, std::span<const PairTdoa> tdoas) {
  // Bins outer, pairs inner: one rotation e^{j w_k tau_p} per pair advanced bin by bin, two
  // pairs per vector (lanes), the pairs' recurrences independent of each other. An odd pair
  // out is paired with a phasor row of zeros.
  using Lanes = double __attribute__((vector_size(16)));
  std::array<int, kMaxPairs + 1> used{};
  int pairs_used = 0;
  for (int p = 0; p < gcc.pair_count() && p < kMaxPairs; ++p)
    if (tdoas[static_cast<std::size_t>(p)].variance_s2 > 0.0)
      used[static_cast<std::size_t>(pairs_used++)] = p;
  if (pairs_used == 0) return 0;
  const int vectors = (pairs_used + 1) / 2;
  const double bin_omega = gcc.bin_omega_rad_per_s();
  std::array<const std::complex<double>*, kMaxPairs + 1> phasors{};
  std::array<double, kMaxPairs + 1> taus{};
  std::array<Lanes, (kMaxPairs + 1) / 2> step_re{}, step_im{}, rotation_re{}, rotation_im{};
  for (int u = 0; u < 2 * vectors; ++u) {
    const auto slot = static_cast<std::size_t>(u);
    const bool real_pair = u < pairs_used;
    taus[slot] = real_pair ? tdoas[static_cast<std::size_t>(used[slot])].tdoa_s : 0.0;
    phasors[slot] = real_pair ? gcc.phasors(used[slot]).data() : zeros_.data();
    const std::complex<double> step = std::polar(1.0, bin_omega * taus[slot]);
    step_re[slot / 2][u % 2] = step.real();
    step_im[slot / 2][u % 2] = step.imag();
  }
  const std::span<std::uint8_t> keep = gcc.bin_keep();
  const double threshold = threshold_ * pairs_used;
  int dropped = 0;
  std::size_t index = 0;
  for (const BandRun& run : gcc.band()) {
    for (int u = 0; u < 2 * vectors; ++u) {
      const auto slot = static_cast<std::size_t>(u);
      const std::complex<double> first = std::polar(1.0, bin_omega * run.first_bin * taus[slot]);
      rotation_re[slot / 2][u % 2] = first.real();
      rotation_im[slot / 2][u % 2] = first.imag();
    }
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      Lanes scores{0.0, 0.0};
      for (int v = 0; v < vectors; ++v) {
        const auto vector = static_cast<std::size_t>(v);
        const std::complex<double> w0 = phasors[2 * vector][index];
        const std::complex<double> w1 = phasors[2 * vector + 1][index];
        const Lanes w_re{w0.real(), w1.real()};
        const Lanes w_im{w0.imag(), w1.imag()};
        const Lanes a_re = rotation_re[vector];
        const Lanes a_im = rotation_im[vector];
        scores += w_re * a_re - w_im * a_im;
        rotation_re[vector] = a_re * step_re[vector] - a_im * step_im[vector];
        rotation_im[vector] = a_re * step_im[vector] + a_im * step_re[vector];
      }
      // Phases decide: a weighted correlation left its weights on the phasors.
      const double scale = gcc.phasor_scale(static_cast<int>(index));
      if (keep[index] != 0 && scores[0] + scores[1] >= threshold * scale) {
        keep[index] = 0;
        ++dropped;
      }
    }
  }
  return dropped;
}

}  // namespace dronetrack::doa
