// The DSP's vector kernels (kernels.hpp), compiled once per Highway target and dispatched at
// run time: GCC-PHAT's (whitening, pair products, kept-bin sums, direct lag sums, Taylor sums
// for the refinement), the ground echo's and the source bin mask's.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "doa/simd/kernels.cpp"
#include "hwy/foreach_target.h"  // IWYU pragma: keep
// foreach_target.h re-includes this file per target: the kernels below are compiled each time.
#include <algorithm>
#include <array>
#include <complex>

#include "doa/doa_measurement.hpp"
#include "doa/simd/dispatch.hpp"
#include "doa/simd/kernels.hpp"
#include "doa/simd/lane_math-inl.hpp"
#include "hwy/highway.h"

HWY_BEFORE_NAMESPACE();
namespace dronetrack::doa::simd::HWY_NAMESPACE {
namespace {

// Whole vectors of the target; at most eight lanes where rows are whole multiples of 8.
using Full = hn::ScalableTag<double>;
using V = hn::Vec<Full>;
using Capped = hn::CappedTag<double, 8>;
using CappedVec = hn::Vec<Capped>;

void UnitPhasors(const UnitRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const auto* spectrum = reinterpret_cast<const double*>(rows.spectrum);
  for (std::size_t n = 0; n < rows.count; n += lanes) {
    const std::size_t count = std::min(lanes, rows.count - n);
    V re, im;
    if (count == lanes &&
        rows.fft_bins[n + lanes - 1] - rows.fft_bins[n] == static_cast<int>(lanes) - 1) {
      // Consecutive FFT bins (within one band run): one interleaved load.
      hn::LoadInterleaved2(d, spectrum + 2 * rows.fft_bins[n], re, im);
    } else {
      HWY_ALIGN double real[kMaxLanes] = {};
      HWY_ALIGN double imag[kMaxLanes] = {};
      for (std::size_t l = 0; l < count; ++l) {
        real[l] = rows.spectrum[rows.fft_bins[n + l]].real();
        imag[l] = rows.spectrum[rows.fft_bins[n + l]].imag();
      }
      re = hn::Load(d, real);
      im = hn::Load(d, imag);
    }
    const V power = hn::MulAdd(re, re, hn::Mul(im, im));
    const V inverse = InverseSqrt(d, power);
    StoreSome(d, power, rows.power + n, count);
    StoreSome(d, hn::Mul(power, inverse), rows.level + n, count);
    StoreSome(d, hn::Mul(re, inverse), rows.unit.re + n, count);
    StoreSome(d, hn::Mul(im, inverse), rows.unit.im + n, count);
  }
}

double PairProducts(const PairRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const V silent = hn::Set(d, rows.silent_level);
  const V one = hn::Set(d, 1.0);
  V total = hn::Zero(d);
  for (std::size_t n = 0; n < rows.count; n += lanes) {
    const std::size_t count = std::min(lanes, rows.count - n);
    const V size =
        hn::Mul(LoadSome(d, rows.level_i + n, count), LoadSome(d, rows.level_j + n, count));
    V live = hn::IfThenElseZero(hn::Gt(size, silent), one);
    if (rows.keep != nullptr) live = hn::Mul(live, LoadKeep(d, rows.keep + n, count));
    const V w = rows.weights != nullptr ? LoadSome(d, rows.weights + n, count) : one;
    const V scale = hn::Mul(live, w);
    V re, im;
    if (rows.given != nullptr) {
      // Length 0 keeps InverseSqrt's huge estimate: 0 times it stays 0.
      LoadSomePairs(d, rows.given + 2 * n, count, re, im);
      const V unit = hn::Mul(InverseSqrt(d, hn::MulAdd(re, re, hn::Mul(im, im))), scale);
      re = hn::Mul(re, unit);
      im = hn::Mul(im, unit);
    } else {
      const V ar = LoadSome(d, rows.a.re + n, count);
      const V ai = LoadSome(d, rows.a.im + n, count);
      const V br = LoadSome(d, rows.b.re + n, count);
      const V bi = LoadSome(d, rows.b.im + n, count);
      re = hn::Mul(hn::MulAdd(ar, br, hn::Mul(ai, bi)), scale);
      im = hn::Mul(hn::MulSub(ai, br, hn::Mul(ar, bi)), scale);
    }
    StoreSomePairs(d, re, im, rows.out + 2 * n, count);
    if (rows.out_floats != nullptr)
      StoreSomePairsDemoted(d, re, im, rows.out_floats + 2 * n, count);
    const V sizes = hn::Mul(size, live);
    StoreSome(d, sizes, rows.magnitude + n, count);
    total = hn::MulAdd(sizes, w, total);
  }
  return SumLanes(d, total);
}

KeptSums KeptBinSums(const KeptRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const V one = hn::Set(d, 1.0);
  V kept_sum = hn::Zero(d), w_sum = kept_sum, w2_sum = kept_sum, omega2_sum = kept_sum;
  V w2_omega2_sum = kept_sum, omega4_sum = kept_sum;
  for (std::size_t n = 0; n < rows.count; n += lanes) {
    const std::size_t count = std::min(lanes, rows.count - n);
    const V keep = LoadKeep(d, rows.keep + n, count);
    // Padding lanes: weight 1 (keep 0 zeroes them; an inverse of 0 would not be).
    const V w = hn::IfThenElse(hn::FirstN(d, count), LoadSome(d, rows.weights + n, count), one);
    const V omega2 = LoadSome(d, rows.omega2 + n, count);
    const V used = rows.weighted ? w : one;
    const V kept_w = hn::Mul(keep, used);
    kept_sum = hn::Add(kept_sum, keep);
    w_sum = hn::Add(w_sum, kept_w);
    w2_sum = hn::MulAdd(kept_w, used, w2_sum);
    omega2_sum = hn::MulAdd(kept_w, omega2, omega2_sum);
    w2_omega2_sum = hn::MulAdd(hn::Mul(kept_w, used), omega2, w2_omega2_sum);
    omega4_sum = hn::MulAdd(hn::Mul(keep, omega2), omega2, omega4_sum);
    const V scale = rows.rescale == Rescale::none     ? keep
                    : rows.rescale == Rescale::weight ? hn::Mul(keep, w)
                                                      : hn::Div(keep, w);
    StoreSome(d, scale, rows.scales + n, count);
    StoreSome(d, keep, rows.keeps + n, count);
  }
  KeptSums out;
  out.kept = SumLanes(d, kept_sum);
  out.w = SumLanes(d, w_sum);
  out.w2 = SumLanes(d, w2_sum);
  out.omega2 = SumLanes(d, omega2_sum);
  out.w2_omega2 = SumLanes(d, w2_omega2_sum);
  out.omega4 = SumLanes(d, omega4_sum);
  return out;
}

double ScaleAndSum(const ScaleRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  V total = hn::Zero(d);
  for (std::size_t n = 0; n < rows.count; n += lanes) {
    const std::size_t count = std::min(lanes, rows.count - n);
    V magnitude = LoadSome(d, rows.magnitudes + n, count);
    if (rows.scale) {
      const V factor = LoadSome(d, rows.scales + n, count);
      V re, im;
      LoadSomePairs(d, rows.phasors + 2 * n, count, re, im);
      re = hn::Mul(re, factor);
      im = hn::Mul(im, factor);
      StoreSomePairs(d, re, im, rows.phasors + 2 * n, count);
      if (rows.phasor_floats != nullptr)
        StoreSomePairsDemoted(d, re, im, rows.phasor_floats + 2 * n, count);
      magnitude = hn::Mul(magnitude, LoadSome(d, rows.keeps + n, count));
      StoreSome(d, magnitude, rows.magnitudes + n, count);
    }
    total = rows.weights != nullptr
                ? hn::MulAdd(magnitude, LoadSome(d, rows.weights + n, count), total)
                : hn::Add(total, magnitude);
  }
  return SumLanes(d, total);
}

// Pairs per pass over the kept bins: four accumulators each plus four table rows must fit the
// registers (32 on AVX-512, NEON and SVE; 16 on AVX2 and SSE4).
#if HWY_ARCH_X86 && HWY_TARGET > HWY_AVX3
constexpr int kGridGroup = 3;
#else
constexpr int kGridGroup = 6;
#endif

// Single precision, as the inverse FFT it replaces: the grid only locates peaks (refinement
// works on the double phasors) and feeds SRP's look-ups; float rounding (~1e-7 of a peak's 1)
// is far below the noise, and twice the lanes halve the cost. At most sixteen lanes: the
// table's rows are whole multiples of 32 lags.
using Floats = hn::CappedTag<float, 16>;
using FloatVec = hn::Vec<Floats>;

// kGridGroup pairs at once, two vectors of lags per block: every table row is loaded once for
// all the group's pairs.
void DirectGrids(const GridJob& job) {
  note_dispatch(HWY_TARGET);
  const Floats d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const int block = 2 * lanes;
  for (int group = 0; group < job.pairs; group += kGridGroup) {
    // A short last group repeats its last pair (its sums are not stored).
    std::array<const float*, kGridGroup> rows{};
    int max_half = 0;
    for (int q = 0; q < kGridGroup; ++q) {
      const int p = std::min(group + q, job.pairs - 1);
      rows[static_cast<std::size_t>(q)] =
          job.phasor_floats + 2 * static_cast<std::size_t>(p) * job.pair_stride;
      max_half = std::max(max_half, job.half_spans[p]);
    }
    for (int first = 0; first <= max_half; first += block) {
      FloatVec cosine_low[kGridGroup], cosine_high[kGridGroup], sine_low[kGridGroup],
          sine_high[kGridGroup];
      for (int q = 0; q < kGridGroup; ++q) {
        cosine_low[q] = hn::Zero(d);
        cosine_high[q] = hn::Zero(d);
        sine_low[q] = hn::Zero(d);
        sine_high[q] = hn::Zero(d);
      }
      for (int n = 0; n < job.kept; ++n) {
        const auto index = static_cast<std::size_t>(job.kept_indices[n]);
        const float* cosines = job.lag_table + index * 2 * job.lag_stride + first;
        const float* sines = cosines + job.lag_stride;
        const FloatVec c_low = hn::LoadU(d, cosines);
        const FloatVec c_high = hn::LoadU(d, cosines + lanes);
        const FloatVec s_low = hn::LoadU(d, sines);
        const FloatVec s_high = hn::LoadU(d, sines + lanes);
        for (int q = 0; q < kGridGroup; ++q) {
          const float* w = rows[static_cast<std::size_t>(q)] + 2 * index;
          const FloatVec re = hn::Set(d, w[0]);
          const FloatVec im = hn::Set(d, w[1]);
          cosine_low[q] = hn::MulAdd(re, c_low, cosine_low[q]);
          cosine_high[q] = hn::MulAdd(re, c_high, cosine_high[q]);
          sine_low[q] = hn::MulAdd(im, s_low, sine_low[q]);
          sine_high[q] = hn::MulAdd(im, s_high, sine_high[q]);
        }
      }
      for (int q = 0; q < kGridGroup && group + q < job.pairs; ++q) {
        HWY_ALIGN float cosine[32] = {};
        HWY_ALIGN float sine[32] = {};
        hn::Store(cosine_low[q], d, cosine);
        hn::Store(cosine_high[q], d, cosine + lanes);
        hn::Store(sine_low[q], d, sine);
        hn::Store(sine_high[q], d, sine + lanes);
        const int half = job.half_spans[group + q];
        double* grid = job.grids + static_cast<std::size_t>(group + q) * job.grid_stride;
        const int last = std::min(half, first + block - 1);
        for (int m = first; m <= last; ++m) {
          const double a = cosine[m - first];
          const double b = sine[m - first];
          grid[half + m] = (a - b) * job.normalisation;
          grid[half - m] = (a + b) * job.normalisation;
        }
      }
    }
  }
}

// Lane l holds bin first + l of a run (rotation e^{j w_k tau} advanced by step^lanes); a run's
// last partial vector has zero phasors in the unused lanes.
TaylorSums BandTaylorSums(const TaylorRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  V sum0 = hn::Zero(d), weighted = sum0, sum1 = sum0, sum2 = sum0, slope = sum0, sum3 = sum0;
  V sum4 = sum0, bend = sum0;
  V step_re, step_im;
  UnitPhasor(d, hn::Set(d, static_cast<double>(lanes) * rows.bin_omega * rows.lag_s), step_re,
             step_im);
  const V omega_step = hn::Set(d, static_cast<double>(lanes) * rows.bin_omega);
  const V bin_omega = hn::Set(d, rows.bin_omega);
  const V lag = hn::Set(d, rows.lag_s);
  const auto* phasors = reinterpret_cast<const double*>(rows.phasors);
  std::size_t index = 0;
  for (std::size_t r = 0; r < rows.run_count; ++r) {
    const BandRun& run = rows.runs[r];
    V omega = hn::Mul(hn::Add(hn::Iota(d, 0.0), hn::Set(d, run.first_bin)), bin_omega);
    V rotation_re, rotation_im;
    UnitPhasor(d, hn::Mul(omega, lag), rotation_re, rotation_im);
    const auto bins = static_cast<std::size_t>(run.last_bin - run.first_bin + 1);
    for (std::size_t k = 0; k < bins; k += lanes) {
      const std::size_t count = std::min(lanes, bins - k);
      V w_re, w_im;
      LoadSomePairs(d, phasors + 2 * index, count, w_re, w_im);
      const V size = LoadSome(d, rows.magnitudes + index, count);
      index += count;
      const V t_re = hn::MulSub(w_re, rotation_re, hn::Mul(w_im, rotation_im));
      const V t_im = hn::MulAdd(w_re, rotation_im, hn::Mul(w_im, rotation_re));
      const V omega2 = hn::Mul(omega, omega);
      sum0 = hn::Add(sum0, t_re);
      weighted = hn::MulAdd(size, t_re, weighted);
      sum1 = hn::NegMulAdd(omega, t_im, sum1);
      slope = hn::NegMulAdd(hn::Mul(omega, size), t_im, slope);
      sum2 = hn::NegMulAdd(omega2, t_re, sum2);
      bend = hn::NegMulAdd(hn::Mul(omega2, size), t_re, bend);
      sum3 = hn::MulAdd(hn::Mul(omega2, omega), t_im, sum3);
      sum4 = hn::MulAdd(hn::Mul(omega2, omega2), t_re, sum4);
      Advance(rotation_re, rotation_im, step_re, step_im);
      omega = hn::Add(omega, omega_step);
    }
  }
  TaylorSums sums;
  sums.r[0] = SumLanes(d, sum0);
  sums.r[1] = SumLanes(d, sum1);
  sums.r[2] = SumLanes(d, sum2);
  sums.r[3] = SumLanes(d, sum3);
  sums.r[4] = SumLanes(d, sum4);
  sums.weighted = SumLanes(d, weighted);
  sums.slope = SumLanes(d, slope);
  sums.bend = SumLanes(d, bend);
  return sums;
}

// ---- ground echo, source bin mask ----

// |c| >= 1 - gain level >= 0.05: the inverse square root needs no guard. Rows are whole
// multiples of 8 bins: at most eight lanes.
double EchoCoherence(const CoherenceRows& rows, double gain) {
  note_dispatch(HWY_TARGET);
  const Capped d;
  const auto lanes = static_cast<int>(hn::Lanes(d));
  const CappedVec one = hn::Set(d, 1.0);
  const CappedVec level = hn::Set(d, gain);
  CappedVec total = hn::Zero(d);
  for (int bin = 0; bin < rows.bins; bin += lanes) {
    CappedVec sum_re = hn::Zero(d);
    CappedVec sum_im = hn::Zero(d);
    for (std::size_t mic = 0; mic < rows.mics; ++mic) {
      const std::size_t at = mic * rows.mic_stride + static_cast<std::size_t>(bin);
      const CappedVec a_re = hn::LoadU(d, rows.aligned.re + at);
      const CappedVec a_im = hn::LoadU(d, rows.aligned.im + at);
      if (gain <= 0.0) {
        sum_re = hn::Add(sum_re, a_re);
        sum_im = hn::Add(sum_im, a_im);
        continue;
      }
      const CappedVec c_re = hn::MulAdd(level, hn::LoadU(d, rows.echo.re + at), one);
      const CappedVec c_im = hn::Mul(level, hn::LoadU(d, rows.echo.im + at));
      const CappedVec inverse = InverseSqrt(d, hn::MulAdd(c_re, c_re, hn::Mul(c_im, c_im)));
      sum_re = hn::MulAdd(hn::MulAdd(a_re, c_re, hn::Mul(a_im, c_im)), inverse, sum_re);
      sum_im = hn::MulAdd(hn::MulSub(a_im, c_re, hn::Mul(a_re, c_im)), inverse, sum_im);
    }
    const CappedVec power = hn::MulAdd(sum_re, sum_re, hn::Mul(sum_im, sum_im));
    total = hn::MulAdd(hn::LoadU(d, rows.weight + bin), power, total);
  }
  return SumLanes(d, total);
}

// The echo by `lanes` interleaved recurrences per run (each lane waits only for its own
// previous product; the error after the band's few dozen steps per lane is ~1e-14).
void CombDivide(const CombRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  V step_re, step_im;
  UnitPhasor(d, hn::Set(d, static_cast<double>(lanes) * rows.phase_step), step_re, step_im);
  const V one = hn::Set(d, 1.0);
  const V level = hn::Set(d, rows.level);
  std::size_t index = 0;
  for (std::size_t r = 0; r < rows.run_count; ++r) {
    const BandRun& run = rows.runs[r];
    V echo_re, echo_im;
    UnitPhasor(
        d,
        hn::Mul(hn::Add(hn::Iota(d, 0.0), hn::Set(d, run.first_bin)), hn::Set(d, rows.phase_step)),
        echo_re, echo_im);
    const auto bins = static_cast<std::size_t>(run.last_bin - run.first_bin + 1);
    for (std::size_t k = 0; k < bins; k += lanes) {
      const std::size_t count = std::min(lanes, bins - k);
      const V c_re = hn::MulAdd(level, echo_re, one);
      const V c_im = hn::Mul(level, echo_im);
      const V inverse = InverseSqrt(d, hn::MulAdd(c_re, c_re, hn::Mul(c_im, c_im)));
      const V u_re = LoadSome(d, rows.unit.re + index, count);
      const V u_im = LoadSome(d, rows.unit.im + index, count);
      StoreSome(d, hn::Mul(hn::MulAdd(u_re, c_re, hn::Mul(u_im, c_im)), inverse),
                rows.out.re + index, count);
      StoreSome(d, hn::Mul(hn::MulSub(u_im, c_re, hn::Mul(u_re, c_im)), inverse),
                rows.out.im + index, count);
      index += count;
      Advance(echo_re, echo_im, step_re, step_im);
    }
  }
}

void PhasorRowsKernel(const PhasorRows& rows) {
  note_dispatch(HWY_TARGET);
  const Capped d;
  const auto lanes = static_cast<int>(hn::Lanes(d));
  const CappedVec time = hn::Set(d, rows.time_s);
  const CappedVec level = hn::Set(d, rows.level);
  for (int bin = 0; bin < rows.bins; bin += lanes) {
    CappedVec re, im;
    UnitPhasor(d, hn::Mul(hn::LoadU(d, rows.omega + bin), time), re, im);
    if (rows.in.re != nullptr) {
      const CappedVec a_re = hn::LoadU(d, rows.in.re + bin);
      const CappedVec a_im = hn::LoadU(d, rows.in.im + bin);
      const CappedVec product_re = hn::MulSub(a_re, re, hn::Mul(a_im, im));
      im = hn::MulAdd(a_re, im, hn::Mul(a_im, re));
      re = product_re;
    }
    hn::StoreU(hn::Mul(re, level), d, rows.out.re + bin);
    hn::StoreU(hn::Mul(im, level), d, rows.out.im + bin);
  }
}

// Per pair the rotations of `lanes` consecutive bins, advanced by step^lanes; pairs summed in
// order, then the bins' verdicts as lanes (which bins a source owns is a coin toss to the branch
// predictor, and a scalar verdict per bin cost as much as the scores).
int DropOwnedBins(const OwnedBinScan& scan) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const int pairs = std::min(scan.pairs, kMaxPairs);
  V rotation_re[kMaxPairs], rotation_im[kMaxPairs], step_re[kMaxPairs], step_im[kMaxPairs];
  for (int p = 0; p < pairs; ++p)
    VectorStep(d, scan.bin_omega, scan.taus[p], step_re[p], step_im[p]);
  const auto* const* phasors = reinterpret_cast<const double* const*>(scan.phasors);
  const V threshold = hn::Set(d, scan.threshold);
  V dropped = hn::Zero(d);  // counts of whole bins: exact
  std::size_t index = 0;
  for (std::size_t r = 0; r < scan.run_count; ++r) {
    const BandRun& run = scan.runs[r];
    for (int p = 0; p < pairs; ++p)
      RunRotation(d, scan.bin_omega, run.first_bin, scan.taus[p], rotation_re[p], rotation_im[p]);
    const auto bins = static_cast<std::size_t>(run.last_bin - run.first_bin + 1);
    for (std::size_t k = 0; k < bins; k += lanes) {
      const std::size_t count = std::min(lanes, bins - k);
      V score = hn::Zero(d);
      for (int p = 0; p < pairs; ++p) {
        V w_re, w_im;
        LoadSomePairs(d, phasors[p] + 2 * index, count, w_re, w_im);
        score = hn::Add(score, hn::MulSub(w_re, rotation_re[p], hn::Mul(w_im, rotation_im[p])));
        Advance(rotation_re[p], rotation_im[p], step_re[p], step_im[p]);
      }
      // Phases decide: a weighted correlation left its weights on the phasors.
      const V limit = scan.scales != nullptr
                          ? hn::Mul(threshold, LoadSome(d, scan.scales + index, count))
                          : threshold;
      const V kept = LoadKeep(d, scan.keep + index, count);
      const V left = hn::IfThenZeroElse(hn::Ge(score, limit), kept);
      dropped = hn::Add(dropped, hn::Sub(kept, left));
      StoreKeep(d, left, scan.keep + index, count);
      index += count;
    }
  }
  return static_cast<int>(SumLanes(d, dropped) + 0.5);
}

// A whole vector of floats per channel and step (LoadInterleaved4 on the target's full float
// width), each widened in two halves to doubles. Per channel one accumulator each for the sum,
// the squares and the peak: the channels' four chains keep the adders busy, and the halves
// meet before they join their chain (a step adds one value to each).
int DeinterleaveFour(const FourChannelRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const auto lanes = static_cast<int>(hn::Lanes(d));
  V sum[4], square[4], peak[4];
  for (int c = 0; c < 4; ++c) {
    sum[c] = hn::Zero(d);
    square[c] = hn::Zero(d);
    peak[c] = hn::Zero(d);
  }
  int n = 0;
#if HWY_TARGET == HWY_SCALAR
  // One lane: no wider float vector to split (the old Atom's fallback), a frame at a time.
  const hn::Rebind<float, Full> floats;
  const int step = lanes;
  for (; n + step <= rows.count; n += step) {
    hn::Vec<decltype(floats)> channel[4];
    hn::LoadInterleaved4(floats, rows.source + 4 * static_cast<std::ptrdiff_t>(n), channel[0],
                         channel[1], channel[2], channel[3]);
    for (int c = 0; c < 4; ++c) {
      const V value = hn::PromoteTo(d, channel[c]);
      hn::StoreU(value, d, rows.target + c * rows.stride + n);
      sum[c] = hn::Add(sum[c], value);
      square[c] = hn::MulAdd(value, value, square[c]);
      peak[c] = hn::Max(peak[c], hn::Abs(value));
    }
  }
#else
  const hn::Repartition<float, Full> floats;
  const hn::Half<decltype(floats)> half;
  const int step = 2 * lanes;
  for (; n + step <= rows.count; n += step) {
    hn::Vec<decltype(floats)> channel[4];
    hn::LoadInterleaved4(floats, rows.source + 4 * static_cast<std::ptrdiff_t>(n), channel[0],
                         channel[1], channel[2], channel[3]);
    for (int c = 0; c < 4; ++c) {
      const V low = hn::PromoteTo(d, hn::LowerHalf(half, channel[c]));
      const V high = hn::PromoteTo(d, hn::UpperHalf(half, channel[c]));
      double* target = rows.target + c * rows.stride + n;
      hn::StoreU(low, d, target);
      hn::StoreU(high, d, target + lanes);
      sum[c] = hn::Add(sum[c], hn::Add(low, high));
      square[c] = hn::Add(square[c], hn::MulAdd(low, low, hn::Mul(high, high)));
      peak[c] = hn::Max(peak[c], hn::Max(hn::Abs(low), hn::Abs(high)));
    }
  }
#endif
  for (int c = 0; c < 4; ++c) {
    rows.sums[c] += SumLanes(d, sum[c]);
    rows.squares[c] += SumLanes(d, square[c]);
    rows.peaks[c] = std::max(rows.peaks[c], hn::GetLane(hn::MaxOfLanes(d, peak[c])));
  }
  return n;
}

}  // namespace
}  // namespace dronetrack::doa::simd::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace dronetrack::doa::simd {

HWY_EXPORT(UnitPhasors);
HWY_EXPORT(PairProducts);
HWY_EXPORT(KeptBinSums);
HWY_EXPORT(ScaleAndSum);
HWY_EXPORT(DirectGrids);
HWY_EXPORT(BandTaylorSums);
HWY_EXPORT(EchoCoherence);
HWY_EXPORT(CombDivide);
HWY_EXPORT(PhasorRowsKernel);
HWY_EXPORT(DropOwnedBins);
HWY_EXPORT(DeinterleaveFour);
void unit_phasors(const UnitRows& rows) { HWY_DYNAMIC_DISPATCH(UnitPhasors)(rows); }
double pair_products(const PairRows& rows) { return HWY_DYNAMIC_DISPATCH(PairProducts)(rows); }
KeptSums kept_sums(const KeptRows& rows) { return HWY_DYNAMIC_DISPATCH(KeptBinSums)(rows); }
double scale_and_sum(const ScaleRows& rows) { return HWY_DYNAMIC_DISPATCH(ScaleAndSum)(rows); }
void direct_grids(const GridJob& job) { HWY_DYNAMIC_DISPATCH(DirectGrids)(job); }
TaylorSums taylor_sums(const TaylorRows& rows) {
  return HWY_DYNAMIC_DISPATCH(BandTaylorSums)(rows);
}

double echo_coherence(const CoherenceRows& rows, double gain) {
  return HWY_DYNAMIC_DISPATCH(EchoCoherence)(rows, gain);
}
void comb_divide(const CombRows& rows) { HWY_DYNAMIC_DISPATCH(CombDivide)(rows); }
void phasor_rows(const PhasorRows& rows) { HWY_DYNAMIC_DISPATCH(PhasorRowsKernel)(rows); }
int drop_owned_bins(const OwnedBinScan& scan) { return HWY_DYNAMIC_DISPATCH(DropOwnedBins)(scan); }

int deinterleave_four(const FourChannelRows& rows) {
  return HWY_DYNAMIC_DISPATCH(DeinterleaveFour)(rows);
}

}  // namespace dronetrack::doa::simd
#endif
