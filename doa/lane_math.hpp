#pragma once
// Arithmetic on GCC/Clang vector-extension lanes shared by the DSP kernels (GccPhat,
// GroundEcho): each kernel body is a template over the lane type V (one double, two doubles in
// SSE2/NEON registers, eight in AVX-512 ones), instantiated once for the portable build and once
// inside a target("avx512f") function chosen at run time.
#include <cstring>

namespace dronetrack::doa {

// Two doubles in one SIMD register (SSE2 on x86-64, NEON on arm64).
using Lanes = double __attribute__((vector_size(16)));

// 1 / sqrt(x) lane by lane. Square roots and divisions dominate per-bin normalisations (~20
// cycles per pair of them): this starts from the exponent-halving bit estimate (within 3.5 %)
// and takes four Newton steps (3.5 % -> 2e-3 -> 5e-6 -> 3e-11 -> rounding). x = 0 keeps the huge
// estimate: x * result stays 0. By reference and always inlined, so that no vector crosses a
// call (no vector ABI between the portable and the AVX-512 code).
template <class V>
[[gnu::always_inline]] inline void inverse_sqrt(const V& x, V& out) {
  // The lanes' comparison type: 64-bit integers, as many as V has doubles (x >= 0, so the
  // signed shift below is the logical one).
  using Bits = decltype(x < x);
  static_assert(sizeof(Bits) == sizeof(V));
  constexpr long long kMagic = 0x5FE6EB50C7B537A9LL;
  Bits bits;
  std::memcpy(&bits, &x, sizeof bits);
  bits = kMagic - (bits >> 1);
  std::memcpy(&out, &bits, sizeof out);
  const V half_x = 0.5 * x;
  for (int step = 0; step < 4; ++step) out = out * (1.5 - half_x * out * out);
}

}  // namespace dronetrack::doa
