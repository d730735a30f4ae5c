#pragma once
// What GccPhat's parts (gcc_phat.cpp, gcc_correlation.cpp, gcc_peaks.cpp) share and its
// interface does not show: tuning constants and the inverse FFT's buffers.
#include <fftw3.h>

#include "doa/gcc_phat.hpp"

namespace dronetrack::doa::gcc_internal {

// Below this |X_i X_j*| a bin carries no phase (digital silence): it gets zero weight.
constexpr double kSilentBin = 1e-30;
constexpr double kMaxPeakRatio = 100.0;
// A correlation from fewer kept bins than this share of the band (7 bins at 1.5-3.5 kHz and
// 8192 points) cannot pin a delay down: a few scattered frequencies alias into many equal
// peaks. Such a frame yields no peak. (Ground interferer, A1: 5 % -> 2 % found the drone in 30
// more frames, same strays; no other bundled scene changes.)
constexpr double kMinKeptShare = 0.02;
// Smallest bin weight: a weighted phasor can be scaled back to plain PHAT (1 / w) exactly.
constexpr double kMinWeight = 1e-3;
// The lag grid is summed directly over the kept bins (single precision) when kept bins x lags
// is below this times N log2 N of the inverse FFT (N = correlation size). Direct sums cost in
// proportion to the products over the target's float lanes; the c2r's cost is FFTW's own.
// Measured with doa_bench's BM_PipelineStage/2 (the whole band, 342 bins x 31 lags x 6 pairs =
// 0.47 products per FFT point at the defaults; x86-64, FFTW 3.3, a loaded machine): direct
// 11.7 us with 4 float lanes (SSE4; NEON has 4 too), 7.6 us with 8 (AVX2), 4.7 us with 16
// (AVX-512), against 13.5-13.7 us for six single-precision c2r of 2048 points: the crossovers
// are ~0.55, ~0.85 and ~1.35 products per FFT point. The factors below sit a little under.
constexpr double kDirectProductsPerFftPoint4 = 0.5;   // 4 float lanes or fewer
constexpr double kDirectProductsPerFftPoint8 = 0.8;   // 8 (AVX2)
constexpr double kDirectProductsPerFftPoint16 = 1.3;  // 16 (AVX-512)
// The band-limited refinement stops when the lag is known to this (1 ns: TDOA noise is
// microseconds, the grid step tens of microseconds).
constexpr double kNewtonResidual_s = 1e-9;

}  // namespace dronetrack::doa::gcc_internal

namespace dronetrack::doa {

// The inverse transform runs in single precision: its lag grid only locates the peaks (the
// refinement maximises the continuous correlation from the double phasors) and feeds SRP's
// look-ups, where float rounding (~1e-7 of a peak) is far below the noise; the transform is a
// third of the whole-band correlation's cost in double.
struct GccPhat::Inverse {
  fftwf_complex* spectrum = nullptr;  // correlation_size/2 + 1
  float* correlation = nullptr;       // correlation_size
  fftwf_plan plan = nullptr;
};

}  // namespace dronetrack::doa
