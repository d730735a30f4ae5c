// The static look's vector kernel (kernels.hpp, `look_phasors`): the averaged phasors
// normalised, the frame's mask, the found sources' bins dropped and the weights applied in one
// pass; compiled once per Highway target and dispatched at run time.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "doa/simd/look_kernels.cpp"
#include "hwy/foreach_target.h"  // IWYU pragma: keep
// foreach_target.h re-includes this file per target: the kernel below is compiled each time.
#include <algorithm>
#include <complex>

#include "doa/doa_measurement.hpp"
#include "doa/simd/dispatch.hpp"
#include "doa/simd/kernels.hpp"
#include "doa/simd/lane_math-inl.hpp"
#include "hwy/highway.h"

HWY_BEFORE_NAMESPACE();
namespace dronetrack::doa::simd::HWY_NAMESPACE {
namespace {

using Full = hn::ScalableTag<double>;
using V = hn::Vec<Full>;

// The same operations, in the same order and lanes, as pair_products (given phasors, unweighted,
// under the mask), drop_owned_bins per source (unscaled) and scale_and_sum after kept_sums'
// weight scales: the phasors, magnitudes and keep bytes come out bit for bit as those four
// passes leave them, but the average, levels and keep bytes are read once, not four times. Only
// the magnitude sums' lanes follow the band's runs (one run: the same sums).
void LookPhasors(const LookRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const int pairs = std::min(rows.pairs, kMaxPairs);
  const int terms = std::min(rows.source_starts[rows.sources], kMaxLookTerms);
  V rotation_re[kMaxLookTerms], rotation_im[kMaxLookTerms];
  V step_re[kMaxLookTerms], step_im[kMaxLookTerms];
  for (int t = 0; t < terms; ++t)
    VectorStep(d, rows.bin_omega, rows.term_taus[t], step_re[t], step_im[t]);
  V unit_re[kMaxPairs], unit_im[kMaxPairs], sizes[kMaxPairs], total[kMaxPairs];
  for (int p = 0; p < pairs; ++p) total[p] = hn::Zero(d);
  const V silent = hn::Set(d, rows.silent_level);
  const V one = hn::Set(d, 1.0);
  std::size_t index = 0;
  for (std::size_t r = 0; r < rows.run_count; ++r) {
    const BandRun& run = rows.runs[r];
    for (int t = 0; t < terms; ++t)
      RunRotation(d, rows.bin_omega, run.first_bin, rows.term_taus[t], rotation_re[t],
                  rotation_im[t]);
    const auto bins = static_cast<std::size_t>(run.last_bin - run.first_bin + 1);
    for (std::size_t k = 0; k < bins; k += lanes) {
      const std::size_t count = std::min(lanes, bins - k);
      V kept = LoadKeep(d, rows.keep + index, count);
      for (int p = 0; p < pairs; ++p) {
        const V size = hn::Mul(LoadSome(d, rows.level_i[p] + index, count),
                               LoadSome(d, rows.level_j[p] + index, count));
        const V live = hn::Mul(hn::IfThenElseZero(hn::Gt(size, silent), one), kept);
        V re, im;
        LoadSomePairs(d, rows.given[p] + 2 * index, count, re, im);
        // Length 0 keeps InverseSqrt's huge estimate: 0 times it stays 0.
        const V unit = hn::Mul(InverseSqrt(d, hn::MulAdd(re, re, hn::Mul(im, im))), live);
        unit_re[p] = hn::Mul(re, unit);
        unit_im[p] = hn::Mul(im, unit);
        sizes[p] = hn::Mul(size, live);
      }
      // Each found source in turn: its bins' verdicts on the normalised average.
      for (int s = 0; s < rows.sources; ++s) {
        V score = hn::Zero(d);
        for (int t = rows.source_starts[s]; t < std::min(rows.source_starts[s + 1], terms); ++t) {
          const int p = rows.term_pairs[t];
          score = hn::Add(
              score, hn::MulSub(unit_re[p], rotation_re[t], hn::Mul(unit_im[p], rotation_im[t])));
          Advance(rotation_re[t], rotation_im[t], step_re[t], step_im[t]);
        }
        kept = hn::IfThenZeroElse(hn::Ge(score, hn::Set(d, rows.thresholds[s])), kept);
      }
      StoreKeep(d, kept, rows.keep + index, count);
      // Padding lanes: weight 1 in the scale (keep 0 zeroes them), 0 in the sums.
      const V weight = LoadSome(d, rows.weights + index, count);
      const V factor = hn::Mul(kept, hn::IfThenElse(hn::FirstN(d, count), weight, one));
      for (int p = 0; p < pairs; ++p) {
        const V re = hn::Mul(unit_re[p], factor);
        const V im = hn::Mul(unit_im[p], factor);
        StoreSomePairs(d, re, im, rows.out[p] + 2 * index, count);
        if (rows.out_floats[p] != nullptr)
          StoreSomePairsDemoted(d, re, im, rows.out_floats[p] + 2 * index, count);
        const V magnitude = hn::Mul(sizes[p], kept);
        StoreSome(d, magnitude, rows.magnitudes[p] + index, count);
        total[p] = hn::MulAdd(magnitude, weight, total[p]);
      }
      index += count;
    }
  }
  for (int p = 0; p < pairs; ++p) rows.magnitude_sums[p] = SumLanes(d, total[p]);
}

}  // namespace
}  // namespace dronetrack::doa::simd::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace dronetrack::doa::simd {

HWY_EXPORT(LookPhasors);
void look_phasors(const LookRows& rows) { HWY_DYNAMIC_DISPATCH(LookPhasors)(rows); }

}  // namespace dronetrack::doa::simd
#endif
