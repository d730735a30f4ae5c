#pragma once
// Band-limited interpolation: a Kaiser-windowed sinc tabulated at `phases` fractional offsets
// (linear interpolation between neighbouring phases), so evaluating a signal between its samples
// costs two short dot products and no trigonometry.
#include <cstddef>
#include <vector>

namespace dronetrack::sim {

class InterpolationKernel {
 public:
  // `half_taps` samples each side; `cutoff` in cycles per input sample (0.5 = Nyquist); rows are
  // normalised to unit DC gain.
  InterpolationKernel(int half_taps, double cutoff, double beta, int phases);

  int half_taps() const { return half_taps_; }
  // Value at `position` (in samples of `samples`), which must have half_taps() valid samples on
  // either side: samples[floor(position) - half_taps + 1 .. floor(position) + half_taps].
  float at(const float* samples, double position) const;

 private:
  int half_taps_;
  int taps_;
  int phases_;
  std::vector<float> table_;  // (phases + 1) rows of taps_ weights
};

// The kernel that evaluates a source signal sampled at twice the output rate and band-limited to
// 0.4 x the output rate (0.2 cycles per source sample): pass-band to 0.2, images from 0.8 on,
// so 16 taps reach ~130 dB of image rejection.
const InterpolationKernel& source_kernel();

}  // namespace dronetrack::sim
