// Lane arithmetic the kernels share, compiled once per Highway target (included from each
// kernel file after hwy/foreach_target.h, hence the toggling guard instead of #pragma once).
#if defined(DRONETRACK_DOA_SIMD_LANE_MATH_INL_) == defined(HWY_TARGET_TOGGLE)
#ifdef DRONETRACK_DOA_SIMD_LANE_MATH_INL_
#undef DRONETRACK_DOA_SIMD_LANE_MATH_INL_
#else
#define DRONETRACK_DOA_SIMD_LANE_MATH_INL_
#endif

#include <algorithm>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <numbers>

#include "hwy/highway.h"

HWY_BEFORE_NAMESPACE();
namespace dronetrack::doa::simd::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// Most doubles in one vector of this target: stack rows for partial vectors.
constexpr std::size_t kMaxLanes = HWY_MAX_BYTES / sizeof(double);

// 1 / sqrt(x) lane by lane. Square roots and divisions dominate per-bin normalisations: this
// starts from the exponent-halving bit estimate (within 3.5 %) and takes four Newton steps
// (3.5 % -> 2e-3 -> 5e-6 -> 3e-11 -> rounding). x = 0 keeps the huge estimate: x * result
// stays 0.
template <class D, class V = hn::Vec<D>>
HWY_INLINE V InverseSqrt(D d, V x) {
  const hn::RebindToUnsigned<D> du;
  constexpr std::uint64_t kMagic = 0x5FE6EB50C7B537A9ULL;
  V out = hn::BitCast(d, hn::Sub(hn::Set(du, kMagic), hn::ShiftRight<1>(hn::BitCast(du, x))));
  const V half_x = hn::Mul(hn::Set(d, 0.5), x);
  const V three_halves = hn::Set(d, 1.5);
  for (int step = 0; step < 4; ++step)
    out = hn::Mul(out, hn::NegMulAdd(hn::Mul(half_x, out), out, three_halves));
  return out;
}

// e^{j phase} lane by lane: phase reduced to whole turns, the half angle (within +-pi/2) by
// Taylor polynomials (through x^17 and x^16: error < 1e-13), then the double angle. No libm
// call per lane; the DSP's phases are thousands of radians at most.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void UnitPhasor(D d, V phase_rad, V& re, V& im) {
  const V turns = hn::Mul(phase_rad, hn::Set(d, 0.5 / std::numbers::pi));
  const V half = hn::Mul(hn::Sub(turns, hn::Round(turns)), hn::Set(d, std::numbers::pi));
  const V x2 = hn::Mul(half, half);
  // 1/n! for the odd (sine) and even (cosine) terms, highest first.
  constexpr double kSine[] = {1.0 / 355687428096000.0,
                              -1.0 / 1307674368000.0,
                              1.0 / 6227020800.0,
                              -1.0 / 39916800.0,
                              1.0 / 362880.0,
                              -1.0 / 5040.0,
                              1.0 / 120.0,
                              -1.0 / 6.0,
                              1.0};
  constexpr double kCosine[] = {1.0 / 20922789888000.0,
                                -1.0 / 87178291200.0,
                                1.0 / 479001600.0,
                                -1.0 / 3628800.0,
                                1.0 / 40320.0,
                                -1.0 / 720.0,
                                1.0 / 24.0,
                                -1.0 / 2.0,
                                1.0};
  V sine = hn::Set(d, kSine[0]);
  V cosine = hn::Set(d, kCosine[0]);
  for (int term = 1; term < 9; ++term) {
    sine = hn::MulAdd(sine, x2, hn::Set(d, kSine[term]));
    cosine = hn::MulAdd(cosine, x2, hn::Set(d, kCosine[term]));
  }
  sine = hn::Mul(sine, half);
  re = hn::Sub(hn::Mul(cosine, cosine), hn::Mul(sine, sine));
  im = hn::Mul(hn::Set(d, 2.0), hn::Mul(sine, cosine));
}

// The steering recurrence the band kernels share: lane l starts at e^{j phase_l} and every step
// (a vector of bins) turns it by e^{j step_rad}; a product per step instead of a cos and a sin
// per bin (the error after a band's hundred steps per lane is ~1e-14).
template <class D, class V = hn::Vec<D>>
HWY_INLINE void StartRotation(D d, V phase_rad, double step_rad, V& re, V& im, V& step_re,
                              V& step_im) {
  UnitPhasor(d, phase_rad, re, im);
  UnitPhasor(d, hn::Set(d, step_rad), step_re, step_im);
}

// (re, im) turned by one step: the complex product (re + j im) (step_re + j step_im).
template <class V>
HWY_INLINE void Advance(V& re, V& im, V step_re, V step_im) {
  const V next_re = hn::MulSub(re, step_re, hn::Mul(im, step_im));
  im = hn::MulAdd(re, step_im, hn::Mul(im, step_re));
  re = next_re;
}

// The rotation by delay `tau_s` of a vector of consecutive bins from `first_bin`, lane l one
// bin further than lane l - 1, stepped in complex double: every kernel that scans a band run
// starts from the same bits.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void RunRotation(D d, double bin_omega, int first_bin, double tau_s, V& re, V& im) {
  HWY_ALIGN double start_re[kMaxLanes];
  HWY_ALIGN double start_im[kMaxLanes];
  const std::complex<double> step = std::polar(1.0, bin_omega * tau_s);
  std::complex<double> rotation = std::polar(1.0, bin_omega * first_bin * tau_s);
  for (std::size_t l = 0; l < hn::Lanes(d); ++l) {
    start_re[l] = rotation.real();
    start_im[l] = rotation.imag();
    rotation *= step;
  }
  re = hn::Load(d, start_re);
  im = hn::Load(d, start_im);
}

// The step that turns such a rotation on by a whole vector of bins (for Advance).
template <class D, class V = hn::Vec<D>>
HWY_INLINE void VectorStep(D d, double bin_omega, double tau_s, V& re, V& im) {
  const std::complex<double> step =
      std::polar(1.0, bin_omega * static_cast<double>(hn::Lanes(d)) * tau_s);
  re = hn::Set(d, step.real());
  im = hn::Set(d, step.imag());
}

// `count` (at most a vector) doubles from `source`, zeros after them.
template <class D, class V = hn::Vec<D>>
HWY_INLINE V LoadSome(D d, const double* source, std::size_t count) {
  if (count == hn::Lanes(d)) return hn::LoadU(d, source);
  HWY_ALIGN double row[kMaxLanes] = {};
  std::memcpy(row, source, count * sizeof(double));
  return hn::Load(d, row);
}

// The first `count` lanes of v to `target`.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void StoreSome(D d, V v, double* target, std::size_t count) {
  if (count == hn::Lanes(d)) {
    hn::StoreU(v, d, target);
    return;
  }
  HWY_ALIGN double row[kMaxLanes];
  hn::Store(v, d, row);
  std::memcpy(target, row, count * sizeof(double));
}

// `count` interleaved (re, im) pairs from `source` split into reals and imaginaries, zeros
// after them.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void LoadSomePairs(D d, const double* source, std::size_t count, V& re, V& im) {
  if (count == hn::Lanes(d)) {
    hn::LoadInterleaved2(d, source, re, im);
    return;
  }
  HWY_ALIGN double row[2 * kMaxLanes] = {};
  std::memcpy(row, source, 2 * count * sizeof(double));
  hn::LoadInterleaved2(d, row, re, im);
}

template <class D, class V = hn::Vec<D>>
HWY_INLINE void StoreSomePairs(D d, V re, V im, double* target, std::size_t count) {
  if (count == hn::Lanes(d)) {
    hn::StoreInterleaved2(re, im, d, target);
    return;
  }
  HWY_ALIGN double row[2 * kMaxLanes];
  hn::StoreInterleaved2(re, im, d, row);
  std::memcpy(target, row, 2 * count * sizeof(double));
}

// The first `count` lanes of re and im as interleaved (re, im) pairs in single precision.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void StoreSomePairsDemoted(D d, V re, V im, float* target, std::size_t count) {
  const hn::Rebind<float, D> floats;
  if (count == hn::Lanes(d)) {
    hn::StoreInterleaved2(hn::DemoteTo(floats, re), hn::DemoteTo(floats, im), floats, target);
    return;
  }
  HWY_ALIGN float row[2 * kMaxLanes];
  hn::StoreInterleaved2(hn::DemoteTo(floats, re), hn::DemoteTo(floats, im), floats, row);
  std::memcpy(target, row, 2 * count * sizeof(float));
}

// `count` keep bytes (0 or 1) as doubles, zeros after them.
template <class D, class V = hn::Vec<D>>
HWY_INLINE V LoadKeep(D d, const std::uint8_t* keep, std::size_t count) {
  if (count == hn::Lanes(d)) {
    // Widened in registers: a row of doubles written lane by lane and loaded as a vector would
    // stall on store forwarding.
    const hn::Rebind<std::uint8_t, D> bytes;
    const hn::Rebind<std::int32_t, D> words;
    return hn::PromoteTo(d, hn::PromoteTo(words, hn::LoadU(bytes, keep)));
  }
  HWY_ALIGN double row[kMaxLanes] = {};
  for (std::size_t l = 0; l < count; ++l) row[l] = keep[l];
  return hn::Load(d, row);
}

// The first `count` lanes of v (each 0 or 1) to `keep` as bytes: LoadKeep's inverse.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void StoreKeep(D d, V v, std::uint8_t* keep, std::size_t count) {
  const hn::Rebind<std::uint8_t, D> bytes;
  const hn::Rebind<std::int32_t, D> words;
  const auto narrow = hn::DemoteTo(bytes, hn::DemoteTo(words, v));
  if (count == hn::Lanes(d)) {
    hn::StoreU(narrow, bytes, keep);
    return;
  }
  HWY_ALIGN std::uint8_t row[kMaxLanes];
  hn::Store(narrow, bytes, row);
  // count < Lanes(d) <= kMaxLanes; the bound says so to GCC, which cannot see it on one-lane
  // targets (-Wstringop-overread).
  std::memcpy(keep, row, std::min(count, sizeof row));
}

template <class D, class V = hn::Vec<D>>
HWY_INLINE double SumLanes(D d, V v) {
  return hn::GetLane(hn::SumOfLanes(d, v));
}

}  // namespace dronetrack::doa::simd::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // DRONETRACK_DOA_SIMD_LANE_MATH_INL_
