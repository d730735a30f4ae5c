// The per-frame statistics' vector kernels (kernels.hpp, "per-frame statistics"): the bin SNR
// weights, the robust regression's middle value, the channel health's sums, the harmonic comb's
// autocorrelation and the acoustic features' steered bins; compiled once per Highway target and
// dispatched at run time.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "doa/simd/stats_kernels.cpp"
#include "hwy/foreach_target.h"  // IWYU pragma: keep
// foreach_target.h re-includes this file per target: the kernels below are compiled each time.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "doa/simd/dispatch.hpp"
#include "doa/simd/kernels.hpp"
#include "doa/simd/lane_math-inl.hpp"
#include "hwy/highway.h"

HWY_BEFORE_NAMESPACE();
namespace dronetrack::doa::simd::HWY_NAMESPACE {
namespace {

using Full = hn::ScalableTag<double>;
using V = hn::Vec<Full>;
using Floats = hn::ScalableTag<float>;
using FloatVec = hn::Vec<Floats>;

// Bin by bin, no branches: whether a bin's SNR is above 0 is a coin toss in noise (a branch per
// bin mispredicted half the time cost more than the arithmetic). Min and Max are std::min and
// std::max for finite values; padding lanes compute on zeros and are not stored.
void SnrWeights(const SnrRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const V smoothing = hn::Set(d, rows.smoothing);
  const V fresh = hn::Set(d, 1.0 - rows.smoothing);
  const V rise = hn::Set(d, rows.rise);
  const V tiny = hn::Set(d, rows.tiny);
  const V bias = hn::Set(d, rows.bias);
  const V one = hn::Set(d, 1.0);
  const V zero = hn::Zero(d);
  const V floor = hn::Set(d, rows.floor);
  for (std::size_t k = 0; k < rows.count; k += lanes) {
    const std::size_t count = std::min(lanes, rows.count - k);
    const V smoothed = hn::Add(hn::Mul(smoothing, LoadSome(d, rows.smoothed + k, count)),
                               hn::Mul(fresh, LoadSome(d, rows.power + k, count)));
    const V risen = hn::Mul(LoadSome(d, rows.noise + k, count), rise);
    const V noise = hn::Max(hn::Min(risen, smoothed), tiny);
    const V snr = hn::Max(hn::Sub(hn::Div(smoothed, hn::Mul(bias, noise)), one), zero);
    const V weight = hn::Max(hn::Div(snr, hn::Add(one, snr)), floor);
    StoreSome(d, smoothed, rows.smoothed + k, count);
    StoreSome(d, noise, rows.noise + k, count);
    StoreSome(d, weight, rows.weights + k, count);
  }
}

// Rank counting: windows hold a dozen points in random order, so every sorting or partitioning
// step is a branch mispredicted half the time; counts are compares and adds without branches
// (sums of 0 and 1 in doubles: exact). A vector of candidates at a time against each value
// broadcast: no reduction across lanes, no partial vector but the candidates' last. The first
// candidate in index order that fits is the answer, as a scalar loop over them would find.
double MiddleValue(const double* values, int count) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const auto size = static_cast<std::size_t>(count);
  const auto middle = static_cast<double>(count / 2);
  const V one = hn::Set(d, 1.0);
  HWY_ALIGN double below_counts[kMaxLanes];
  HWY_ALIGN double equal_counts[kMaxLanes];
  for (std::size_t i = 0; i < size; i += lanes) {
    const std::size_t some = std::min(lanes, size - i);
    const V candidate = LoadSome(d, values + i, some);
    V below = hn::Zero(d);
    V equal = hn::Zero(d);
    for (std::size_t j = 0; j < size; ++j) {
      const V other = hn::Set(d, values[j]);
      below = hn::Add(below, hn::IfThenElseZero(hn::Lt(other, candidate), one));
      equal = hn::Add(equal, hn::IfThenElseZero(hn::Eq(other, candidate), one));
    }
    hn::Store(below, d, below_counts);
    hn::Store(equal, d, equal_counts);
    for (std::size_t l = 0; l < some; ++l)
      if (below_counts[l] <= middle && middle < below_counts[l] + equal_counts[l])
        return values[i + l];
  }
  return values[count / 2];  // not reached for finite values
}

// The run as one flat array of floats in steps of whole periods (a multiple of both the channel
// count and the lanes), so lane j of step vector v always holds channel (v lanes + j) % channels
// and the sums stay in registers; at least four vectors a step, so that no addition waits for
// the previous one. A non-finite sample makes its channel's sum of squares non-finite, so the
// caller needs no per-sample test when the sums are finite; the peak keeps the larger by a
// compare, as the scalar tail does (NaN: the squares tell).
template <int kChannels>
void ChannelSumsOf(const InterleavedRows& rows) {
  const Floats d;
  constexpr std::size_t kLanes = hn::MaxLanes(Floats());
  constexpr std::size_t kPeriod = std::lcm(static_cast<std::size_t>(kChannels), kLanes);
  constexpr std::size_t kPeriodVectors = kPeriod / kLanes;
  constexpr std::size_t kVectors = kPeriodVectors * ((4 + kPeriodVectors - 1) / kPeriodVectors);
  constexpr std::size_t kStep = kVectors * kLanes;
  FloatVec sum[kVectors], square[kVectors], peak[kVectors];
  for (std::size_t v = 0; v < kVectors; ++v) {
    sum[v] = hn::Zero(d);
    square[v] = hn::Zero(d);
    peak[v] = hn::Zero(d);
  }
  const std::size_t total = rows.frames * kChannels;
  std::size_t i = 0;
  for (; i + kStep <= total; i += kStep) {
    for (std::size_t v = 0; v < kVectors; ++v) {
      const FloatVec value = hn::LoadU(d, rows.interleaved + i + v * kLanes);
      sum[v] = hn::Add(sum[v], value);
      square[v] = hn::Add(square[v], hn::Mul(value, value));
      const FloatVec size = hn::Abs(value);
      peak[v] = hn::IfThenElse(hn::Gt(peak[v], size), peak[v], size);
    }
  }
  HWY_ALIGN float lane_sum[kStep], lane_square[kStep], lane_peak[kStep];
  for (std::size_t v = 0; v < kVectors; ++v) {
    hn::Store(sum[v], d, lane_sum + v * kLanes);
    hn::Store(square[v], d, lane_square + v * kLanes);
    hn::Store(peak[v], d, lane_peak + v * kLanes);
  }
  for (std::size_t j = 0; i < total; ++i, ++j) {  // whole frames: j % kChannels is the channel
    const float value = rows.interleaved[i];
    lane_sum[j] += value;
    lane_square[j] += value * value;
    lane_peak[j] = std::isnan(value) ? value : std::max(lane_peak[j], std::fabs(value));
  }
  for (int c = 0; c < kChannels; ++c) {
    rows.sums[c] = 0.0F;
    rows.squares[c] = 0.0F;
    rows.peaks[c] = 0.0F;
  }
  for (std::size_t j = 0; j < kStep; ++j) {
    const std::size_t c = j % kChannels;
    rows.sums[c] += lane_sum[j];
    rows.squares[c] += lane_square[j];
    rows.peaks[c] = std::max(rows.peaks[c], lane_peak[j]);
  }
}

void ChannelSums(const InterleavedRows& rows) {
  note_dispatch(HWY_TARGET);
  using Sums = void (*)(const InterleavedRows&);
  constexpr Sums kSumsOf[kMaxInterleavedChannels] = {
      ChannelSumsOf<1>, ChannelSumsOf<2>, ChannelSumsOf<3>, ChannelSumsOf<4>,
      ChannelSumsOf<5>, ChannelSumsOf<6>, ChannelSumsOf<7>, ChannelSumsOf<8>};
  kSumsOf[std::clamp(rows.channels, 1, kMaxInterleavedChannels) - 1](rows);
}

// Two running sums (one would make every product wait for the previous addition); the order
// differs from a plain loop's, which an autocorrelation normalised to [-1, 1] does not mind.
float LaggedProduct(const float* a, int n, int lag) {
  note_dispatch(HWY_TARGET);
  const Floats d;
  const auto lanes = static_cast<int>(hn::Lanes(d));
  const int count = n - lag;
  FloatVec sum0 = hn::Zero(d);
  FloatVec sum1 = hn::Zero(d);
  int i = 0;
  for (; i + 2 * lanes <= count; i += 2 * lanes) {
    sum0 = hn::MulAdd(hn::LoadU(d, a + i), hn::LoadU(d, a + i + lag), sum0);
    sum1 = hn::MulAdd(hn::LoadU(d, a + i + lanes), hn::LoadU(d, a + i + lag + lanes), sum1);
  }
  float sum = hn::GetLane(hn::SumOfLanes(d, hn::Add(sum0, sum1)));
  for (; i < count; ++i) sum += a[i] * a[i + lag];
  return sum;
}

// Lane l holds bin first + l (+ a vector per step); each source's and mic's steering phasor
// starts at e^{j w_k delay} per lane and is advanced by e^{j lanes w delay} (the error after a
// band's hundred steps per lane is ~1e-14). The owner is chosen lane by lane with compares and
// selects, sources in order, as the scalar rule does; a partial last vector's lanes have zero
// spectra and own nothing.
void SteeredBinsKernel(const SteeredBins& job) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const int sources = std::min(job.sources, kMaxSteeredSources);
  const int mics = std::min(job.mics, kMaxSteeredMics);
  const V zero = hn::Zero(d);
  const V mic_count = hn::Set(d, static_cast<double>(mics));
  const V first_omega =
      hn::Mul(hn::Add(hn::Iota(d, 0.0), hn::Set(d, job.first_bin)), hn::Set(d, job.bin_omega));
  // Rotations and steps as rows of vectors (sources x mics): they do not all fit in registers.
  HWY_ALIGN double rotation_re[kMaxSteeredSources * kMaxSteeredMics * kMaxLanes];
  HWY_ALIGN double rotation_im[kMaxSteeredSources * kMaxSteeredMics * kMaxLanes];
  HWY_ALIGN double step_re[kMaxSteeredSources * kMaxSteeredMics * kMaxLanes];
  HWY_ALIGN double step_im[kMaxSteeredSources * kMaxSteeredMics * kMaxLanes];
  for (int s = 0; s < sources; ++s) {
    for (int m = 0; m < mics; ++m) {
      const double delay = job.delays_s[static_cast<std::size_t>(s) * job.delay_stride +
                                        static_cast<std::size_t>(m)];
      const std::size_t at = static_cast<std::size_t>(s * mics + m) * lanes;
      V re, im, turn_re, turn_im;
      StartRotation(d, hn::Mul(first_omega, hn::Set(d, delay)),
                    static_cast<double>(lanes) * job.bin_omega * delay, re, im, turn_re, turn_im);
      hn::Store(re, d, rotation_re + at);
      hn::Store(im, d, rotation_im + at);
      hn::Store(turn_re, d, step_re + at);
      hn::Store(turn_im, d, step_im + at);
    }
  }
  const auto bins = static_cast<std::size_t>(job.bins);
  for (std::size_t k = 0; k < bins; k += lanes) {
    const std::size_t count = std::min(lanes, bins - k);
    V x_re[kMaxSteeredMics], x_im[kMaxSteeredMics];
    V energy = zero;
    for (int m = 0; m < mics; ++m) {
      const auto* spectrum = reinterpret_cast<const double*>(job.spectra[m] + job.first_bin);
      LoadSomePairs(d, spectrum + 2 * k, count, x_re[m], x_im[m]);
      energy = hn::MulAdd(x_re[m], x_re[m], hn::MulAdd(x_im[m], x_im[m], energy));
    }
    StoreSome(d, hn::Div(energy, mic_count), job.mic_power + k, count);
    const auto live = hn::Gt(energy, zero);
    const V scaled_energy = hn::Mul(mic_count, energy);
    V best = hn::Set(d, job.min_coherence);
    V owner = hn::Set(d, -1.0);
    V owner_power = zero;
    for (int s = 0; s < sources; ++s) {
      V sum_re = zero, sum_im = zero;
      for (int m = 0; m < mics; ++m) {
        const std::size_t at = static_cast<std::size_t>(s * mics + m) * lanes;
        V r_re = hn::Load(d, rotation_re + at);
        V r_im = hn::Load(d, rotation_im + at);
        sum_re = hn::Add(sum_re, hn::MulSub(x_re[m], r_re, hn::Mul(x_im[m], r_im)));
        sum_im = hn::Add(sum_im, hn::MulAdd(x_re[m], r_im, hn::Mul(x_im[m], r_re)));
        Advance(r_re, r_im, hn::Load(d, step_re + at), hn::Load(d, step_im + at));
        hn::Store(r_re, d, rotation_re + at);
        hn::Store(r_im, d, rotation_im + at);
      }
      const V coherent = hn::MulAdd(sum_re, sum_re, hn::Mul(sum_im, sum_im));
      const auto wins = hn::And(live, hn::Ge(coherent, hn::Mul(hn::Mul(best, mic_count), energy)));
      // Lanes with no energy lose (not a division by 0 that would be kept).
      best = hn::IfThenElse(wins, hn::Div(coherent, hn::IfThenElse(live, scaled_energy, mic_count)),
                            best);
      owner = hn::IfThenElse(wins, hn::Set(d, static_cast<double>(s)), owner);
      owner_power = hn::IfThenElse(wins, hn::Div(coherent, mic_count), owner_power);
    }
    for (int s = 0; s < sources; ++s)
      StoreSome(d,
                hn::IfThenElseZero(hn::Eq(owner, hn::Set(d, static_cast<double>(s))), owner_power),
                job.source_power + static_cast<std::size_t>(s) * bins + k, count);
  }
}

// average = keep x average + (1 - keep) x fresh, lane by lane: the same two products and sum
// per value as the scalar expression (no reduction).
void ExponentialAverage(const AverageRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const V old_share = hn::Set(d, rows.keep_share);
  const V new_share = hn::Set(d, 1.0 - rows.keep_share);
  for (std::size_t n = 0; n < rows.count; n += hn::Lanes(d)) {
    const std::size_t count = std::min(hn::Lanes(d), rows.count - n);
    const V blend = hn::Add(hn::Mul(old_share, LoadSome(d, rows.average + n, count)),
                            hn::Mul(new_share, LoadSome(d, rows.fresh + n, count)));
    StoreSome(d, blend, rows.average + n, count);
  }
}

// Lane l holds bin first_bin + l (+ a vector per step); the steering e^{j w_k tdoa} starts per
// lane from the polynomial phasor and is advanced by e^{j lanes w tdoa} (~1e-14 after a band's
// hundred steps per lane), instead of a cos and a sin per bin. A dropped bin adds 0 to both
// rows; a partial last vector's lanes are not stored.
void SteeredAgreementKernel(const AgreementRows& rows) {
  note_dispatch(HWY_TARGET);
  const Full d;
  const std::size_t lanes = hn::Lanes(d);
  const double turn = rows.bin_omega * rows.tdoa_s;
  V rotation_re, rotation_im, step_re, step_im;
  StartRotation(d, hn::Mul(hn::Add(hn::Iota(d, 0.0), hn::Set(d, rows.first_bin)), hn::Set(d, turn)),
                static_cast<double>(lanes) * turn, rotation_re, rotation_im, step_re, step_im);
  for (std::size_t n = 0; n < rows.count; n += lanes) {
    const std::size_t count = std::min(lanes, rows.count - n);
    const V ar = LoadSome(d, rows.a.re + n, count);
    const V ai = LoadSome(d, rows.a.im + n, count);
    const V br = LoadSome(d, rows.b.re + n, count);
    const V bi = LoadSome(d, rows.b.im + n, count);
    // a b* = (ar br + ai bi) + j (ai br - ar bi); its real part after the steering.
    const V phasor_re = hn::MulAdd(ar, br, hn::Mul(ai, bi));
    const V phasor_im = hn::MulSub(ai, br, hn::Mul(ar, bi));
    const V agreement = hn::Mul(hn::MulSub(phasor_re, rotation_re, hn::Mul(phasor_im, rotation_im)),
                                LoadKeep(d, rows.keep + n, count));
    StoreSome(d,
              hn::MulAdd(LoadSome(d, rows.magnitude + n, count), agreement,
                         LoadSome(d, rows.power + n, count)),
              rows.power + n, count);
    StoreSome(d, hn::Add(LoadSome(d, rows.agreement + n, count), agreement), rows.agreement + n,
              count);
    Advance(rotation_re, rotation_im, step_re, step_im);
  }
}
}  // namespace
}  // namespace dronetrack::doa::simd::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace dronetrack::doa::simd {

HWY_EXPORT(SnrWeights);
HWY_EXPORT(MiddleValue);
HWY_EXPORT(ChannelSums);
HWY_EXPORT(LaggedProduct);
HWY_EXPORT(SteeredBinsKernel);
HWY_EXPORT(ExponentialAverage);
HWY_EXPORT(SteeredAgreementKernel);
void snr_weights(const SnrRows& rows) { HWY_DYNAMIC_DISPATCH(SnrWeights)(rows); }
double middle_value(const double* values, int count) {
  return HWY_DYNAMIC_DISPATCH(MiddleValue)(values, count);
}
void channel_sums(const InterleavedRows& rows) { HWY_DYNAMIC_DISPATCH(ChannelSums)(rows); }
float lagged_product(const float* a, int n, int lag) {
  return HWY_DYNAMIC_DISPATCH(LaggedProduct)(a, n, lag);
}
void steered_bins(const SteeredBins& job) { HWY_DYNAMIC_DISPATCH(SteeredBinsKernel)(job); }
void exponential_average(const AverageRows& rows) {
  HWY_DYNAMIC_DISPATCH(ExponentialAverage)(rows);
}
void steered_agreement(const AgreementRows& rows) {
  HWY_DYNAMIC_DISPATCH(SteeredAgreementKernel)(rows);
}

}  // namespace dronetrack::doa::simd
#endif
