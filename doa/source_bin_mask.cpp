#include "doa/source_bin_mask.hpp"
#include "doa/vector_shuffle.hpp"

#include <algorithm>
#include <array>
#include <complex>
#include <cstring>

namespace dronetrack::doa {

namespace {

using Lanes = double __attribute__((vector_size(16)));
constexpr int kMaxVectors = (kMaxPairs + 1) / 2;

struct BinScan {
  const GccPhat& gcc;
  double bin_omega;
  const std::complex<double>* const* phasors;  // 2 x vectors rows (an odd pair out: zeros)
  const double* taus;
  const Lanes* step_re;
  const Lanes* step_im;
  double threshold;
  std::span<std::uint8_t> keep;
};

// The scan over the band for `vectors` pair vectors; Vectors > 0 fixes the count at compile
// time (up to 6 pairs, 4 mics) so the rotations stay in registers instead of going through
// memory bin by bin.
template <int Vectors>
int scan_bins(const BinScan& scan, int vectors) {
  constexpr int kSize = Vectors > 0 ? Vectors : kMaxVectors;
  const int count = Vectors > 0 ? Vectors : vectors;
  Lanes rotation_re[kSize] = {};
  Lanes rotation_im[kSize] = {};
  Lanes step_re[kSize] = {};
  Lanes step_im[kSize] = {};
  for (int v = 0; v < count; ++v) {
    step_re[v] = scan.step_re[v];
    step_im[v] = scan.step_im[v];
  }
  int dropped = 0;
  std::size_t index = 0;
  for (const BandRun& run : scan.gcc.band()) {
    for (int v = 0; v < count; ++v) {
      const std::complex<double> first0 =
          std::polar(1.0, scan.bin_omega * run.first_bin * scan.taus[2 * v]);
      const std::complex<double> first1 =
          std::polar(1.0, scan.bin_omega * run.first_bin * scan.taus[2 * v + 1]);
      rotation_re[v] = Lanes{first0.real(), first1.real()};
      rotation_im[v] = Lanes{first0.imag(), first1.imag()};
    }
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      Lanes scores{0.0, 0.0};
      for (int v = 0; v < count; ++v) {
        const std::complex<double> w0 = scan.phasors[2 * v][index];
        const std::complex<double> w1 = scan.phasors[2 * v + 1][index];
        const Lanes w_re{w0.real(), w1.real()};
        const Lanes w_im{w0.imag(), w1.imag()};
        const Lanes a_re = rotation_re[v];
        const Lanes a_im = rotation_im[v];
        scores += w_re * a_re - w_im * a_im;
        rotation_re[v] = a_re * step_re[v] - a_im * step_im[v];
        rotation_im[v] = a_re * step_im[v] + a_im * step_re[v];
      }
      // Phases decide: a weighted correlation left its weights on the phasors.
      const double scale = scan.gcc.phasor_scale(static_cast<int>(index));
      if (scan.keep[index] != 0 && scores[0] + scores[1] >= scan.threshold * scale) {
        scan.keep[index] = 0;
        ++dropped;
      }
    }
  }
  return dropped;
}

#if defined(__x86_64__) && defined(__GNUC__)
// The scan eight bins per vector (GccPhat::wide_simd()): per pair the rotations of eight
// consecutive bins, advanced by step^8; pairs summed in order, then the bins' verdicts.
__attribute__((target("avx512f,fma"))) int wide_scan_bins(const BinScan& scan, int pairs) {
  using Wide = double __attribute__((vector_size(64)));
  using Selector = long long __attribute__((vector_size(64)));
  constexpr int kLanes = 8;
  Wide rotation_re[kMaxPairs] = {};
  Wide rotation_im[kMaxPairs] = {};
  Wide step8_re[kMaxPairs] = {};
  Wide step8_im[kMaxPairs] = {};
  for (int p = 0; p < pairs; ++p) {
    std::complex<double> step8 = std::polar(1.0, scan.bin_omega * kLanes * scan.taus[p]);
    step8_re[p] = Wide{} + step8.real();
    step8_im[p] = Wide{} + step8.imag();
  }
  int dropped = 0;
  std::size_t index = 0;
  for (const BandRun& run : scan.gcc.band()) {
    for (int p = 0; p < pairs; ++p) {
      const std::complex<double> step = std::polar(1.0, scan.bin_omega * scan.taus[p]);
      std::complex<double> rotation =
          std::polar(1.0, scan.bin_omega * run.first_bin * scan.taus[p]);
      for (int l = 0; l < kLanes; ++l) {
        rotation_re[p][l] = rotation.real();
        rotation_im[p][l] = rotation.imag();
        rotation *= step;
      }
    }
    const int bins = run.last_bin - run.first_bin + 1;
    for (int k = 0; k < bins; k += kLanes, index += kLanes) {
      const int lanes = std::min(kLanes, bins - k);
      Wide scores{};
      for (int p = 0; p < pairs; ++p) {
        const std::complex<double>* w = scan.phasors[p] + index;
        Wide w_re, w_im;
        if (lanes == kLanes) {
          Wide first_half, second_half;
          std::memcpy(&first_half, w, sizeof first_half);
          std::memcpy(&second_half, w + 4, sizeof second_half);
          w_re = DRONETRACK_SHUFFLE(first_half, second_half, Selector, 0, 2, 4, 6, 8, 10, 12, 14);
          w_im = DRONETRACK_SHUFFLE(first_half, second_half, Selector, 1, 3, 5, 7, 9, 11, 13, 15);
        } else {
          for (int l = 0; l < kLanes; ++l) {
            w_re[l] = l < lanes ? w[l].real() : 0.0;
            w_im[l] = l < lanes ? w[l].imag() : 0.0;
          }
        }
        scores += w_re * rotation_re[p] - w_im * rotation_im[p];
        const Wide next_re = rotation_re[p] * step8_re[p] - rotation_im[p] * step8_im[p];
        rotation_im[p] = rotation_re[p] * step8_im[p] + rotation_im[p] * step8_re[p];
        rotation_re[p] = next_re;
      }
      for (int l = 0; l < lanes; ++l) {
        const std::size_t bin = index + static_cast<std::size_t>(l);
        // Phases decide: a weighted correlation left its weights on the phasors. No branch:
        // which bins a source owns is a coin toss to the branch predictor.
        const double scale = scan.gcc.phasor_scale(static_cast<int>(bin));
        const int owned = scores[l] >= scan.threshold * scale ? 1 : 0;
        const int was_kept = scan.keep[bin] != 0 ? 1 : 0;
        dropped += was_kept & owned;
        scan.keep[bin] = static_cast<std::uint8_t>(was_kept & (1 - owned));
      }
    }
    index -= static_cast<std::size_t>((kLanes - bins % kLanes) % kLanes);
  }
  return dropped;
}
#define DRONETRACK_WIDE_SIMD 1
#endif

}  // namespace

SourceBinMask::SourceBinMask(const GccPhat& gcc, double threshold)
    : threshold_(threshold), zeros_(static_cast<std::size_t>(gcc.band_bin_count())) {}

int SourceBinMask::drop(GccPhat& gcc, std::span<const PairTdoa> tdoas) {
  // Bins outer, pairs inner: one rotation e^{j w_k tau_p} per pair advanced bin by bin, two
  // pairs per vector (lanes), the pairs' recurrences independent of each other. An odd pair
  // out is paired with a phasor row of zeros.
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
  std::array<Lanes, kMaxVectors> step_re{}, step_im{};
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
  const BinScan scan{
      gcc, bin_omega, phasors.data(), taus.data(), step_re.data(), step_im.data(), threshold, keep};
#ifdef DRONETRACK_WIDE_SIMD
  if (gcc.wide_simd()) return wide_scan_bins(scan, pairs_used);
#endif
  switch (vectors) {
    case 1:
      return scan_bins<1>(scan, vectors);
    case 2:
      return scan_bins<2>(scan, vectors);
    case 3:
      return scan_bins<3>(scan, vectors);
    default:
      return scan_bins<0>(scan, vectors);
  }
}

}  // namespace dronetrack::doa
