#pragma once
// Arithmetic on GCC/Clang vector-extension lanes shared by the DSP kernels (GccPhat,
// GroundEcho): each kernel body is a template over the lane type V (two doubles in
// SSE2/NEON registers, eight in AVX-512 ones), instantiated once for the portable build and once
// inside a target("avx512f") function chosen at run time.
#include <cstddef>
#include <cstring>
#include <numbers>

namespace dronetrack::doa {

// Two doubles in one SIMD register (SSE2 on x86-64, NEON on arm64).
using Lanes = double __attribute__((vector_size(16)));

// Unsigned 64-bit integer lanes as wide as a vector of doubles (for bit tricks on them).
template <std::size_t kBytes>
struct UnsignedLanes;
template <>
struct UnsignedLanes<16> {
  using type = unsigned long long __attribute__((vector_size(16)));
};
template <>
struct UnsignedLanes<64> {
  using type = unsigned long long __attribute__((vector_size(64)));
};

// 1 / sqrt(x) lane by lane. Square roots and divisions dominate per-bin normalisations (~20
// cycles per pair of them): this starts from the exponent-halving bit estimate (within 3.5 %)
// and takes four Newton steps (3.5 % -> 2e-3 -> 5e-6 -> 3e-11 -> rounding). x = 0 keeps the huge
// estimate: x * result stays 0. By reference and always inlined, so that no vector crosses a
// call (no vector ABI between the portable and the AVX-512 code).
template <class V>
[[gnu::always_inline]] inline void inverse_sqrt(const V& x, V& out) {
  using Bits = typename UnsignedLanes<sizeof(V)>::type;
  constexpr unsigned long long kMagic = 0x5FE6EB50C7B537A9ULL;
  Bits bits;
  std::memcpy(&bits, &x, sizeof bits);
  bits = kMagic - (bits >> 1);
  std::memcpy(&out, &bits, sizeof out);
  const V half_x = 0.5 * x;
  for (int step = 0; step < 4; ++step) out = out * (1.5 - half_x * out * out);
}

// e^{j phase} lane by lane: phase reduced to whole turns, the half angle (within +-pi/2) by
// Taylor polynomials (through x^17 and x^16: error < 1e-13), then the double angle. Exact
// rounding (the 2^52 trick) needs |phase| < 2^51 turns; the DSP's phases are thousands of
// radians at most.
template <class V>
[[gnu::always_inline]] inline void unit_phasor(const V& phase_rad, V& re, V& im) {
  constexpr double kRound = 6755399441055744.0;  // 1.5 * 2^52: adding it rounds to an integer
  const V turns = phase_rad * (0.5 / std::numbers::pi);
  const V whole = (turns + kRound) - kRound;
  const V half = (turns - whole) * std::numbers::pi;
  const V x2 = half * half;
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
  V sine = V{} + kSine[0];
  V cosine = V{} + kCosine[0];
  for (int term = 1; term < 9; ++term) {
    sine = sine * x2 + kSine[term];
    cosine = cosine * x2 + kCosine[term];
  }
  sine *= half;
  re = cosine * cosine - sine * sine;
  im = 2.0 * sine * cosine;
}

}  // namespace dronetrack::doa
