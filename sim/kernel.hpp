#pragma once
// Band-limited interpolation: a Kaiser-windowed sinc tabulated at `phases` fractional offsets
// (linear interpolation between neighbouring phases), so evaluating a signal between its samples
// costs two short dot products and no trigonometry.
#include <cstddef>
#include <vector>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace dronetrack::sim {

class InterpolationKernel {
 public:
  // `half_taps` samples each side; `cutoff` in cycles per input sample (0.5 = Nyquist); rows are
  // normalised to unit DC gain.
  InterpolationKernel(int half_taps, double cutoff, double beta, int phases);

  int half_taps() const { return half_taps_; }
  // Value at `position` >= 0 (in samples of `samples`), which must have half_taps() valid
  // samples on either side: samples[floor(position) - half_taps + 1 .. floor(position) +
  // half_taps].
  float at(const float* samples, double position) const;

 private:
  int half_taps_;
  int taps_;
  int phases_;
  std::vector<float> table_;  // (phases + 1) rows of taps_ weights
};

// The kernel that evaluates a source signal sampled at twice the output rate and band-limited to
// 0.4 x the output rate (0.2 cycles per source sample): pass-band to 0.2, images from 0.8 on,
// so 12 taps reach ~100 dB of image rejection.
const InterpolationKernel& source_kernel();

inline float InterpolationKernel::at(const float* samples, double position) const {
  // Positions are never negative here, so truncation is the floor (and needs no libm call).
  const auto whole = static_cast<std::ptrdiff_t>(position);
  const double floor_position = static_cast<double>(whole);
  const double phase_position = (position - floor_position) * phases_;
  int phase = static_cast<int>(phase_position);
  if (phase >= phases_) phase = phases_ - 1;
  const float blend = static_cast<float>(phase_position - phase);
  const float* row0 = table_.data() + static_cast<std::ptrdiff_t>(phase) * taps_;
  const float* row1 = row0 + taps_;
  const float* first = samples + whole - half_taps_ + 1;
#if defined(__SSE2__)
  // Hot loop of the simulator (tens of millions of calls per scene): explicit SSE, which every
  // x86-64 has.
  __m128 sum0 = _mm_setzero_ps();
  __m128 sum1 = _mm_setzero_ps();
  for (int tap = 0; tap < taps_; tap += 4) {
    const __m128 values = _mm_loadu_ps(first + tap);
    sum0 = _mm_add_ps(sum0, _mm_mul_ps(values, _mm_loadu_ps(row0 + tap)));
    sum1 = _mm_add_ps(sum1, _mm_mul_ps(values, _mm_loadu_ps(row1 + tap)));
  }
  __m128 sum = _mm_add_ps(sum0, _mm_mul_ps(_mm_set1_ps(blend), _mm_sub_ps(sum1, sum0)));
  __m128 swapped = _mm_shuffle_ps(sum, sum, _MM_SHUFFLE(2, 3, 0, 1));
  sum = _mm_add_ps(sum, swapped);
  swapped = _mm_movehl_ps(swapped, sum);
  sum = _mm_add_ss(sum, swapped);
  return _mm_cvtss_f32(sum);
#else
  float sum0 = 0.0f;
  float sum1 = 0.0f;
  for (int tap = 0; tap < taps_; ++tap) {
    sum0 += first[tap] * row0[tap];
    sum1 += first[tap] * row1[tap];
  }
  return sum0 + blend * (sum1 - sum0);
#endif
}

}  // namespace dronetrack::sim
