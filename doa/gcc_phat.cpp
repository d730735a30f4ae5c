#include "doa/gcc_phat.hpp"

#include <fftw3.h>

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "doa/fftw_lock.hpp"
#include "doa/lane_math.hpp"
#include "doa/vector_shuffle.hpp"

namespace dronetrack::doa {

namespace {
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
// The lag grid is summed directly over the kept bins when kept bins x lags is below this times
// N log2 N of the inverse FFT (N = correlation size); measured with doa_bench's
// BM_PipelineStage (direct and FFT cost the same at about this ratio on x86-64 with FFTW 3.3).
constexpr double kDirectProductsPerFftPoint = 0.25;
// Lags per block of direct_grids(): 2 x kLagBlock running sums fit the SIMD registers.
constexpr int kLagBlock = 8;
// The lag table's rows are whole multiples of this (zeros after the last lag): the wide
// kernel's lag block.
constexpr int kLagStrideMultiple = 16;
// The band-limited refinement stops when the lag is known to this (1 ns: TDOA noise is
// microseconds, the grid step tens of microseconds).
constexpr double kNewtonResidual_s = 1e-9;

// prepare()'s per-bin pass, shared by every pair: the kept bins' sums (weights, their squares,
// w^2 and w^4 terms for the normalisation, TDOA variance and Taylor bound) and each bin's scale
// (keep x the weight, its inverse or 1) and keep as doubles.
struct KeptSums {
  double kept = 0.0;  // how many bins are kept (sums of 0 and 1: exact)
  double w = 0.0;
  double w2 = 0.0;
  double omega2 = 0.0;
  double w2_omega2 = 0.0;
  double omega4 = 0.0;
};
enum class Rescale { none, weight, inverse };

struct KeptRows {
  const std::uint8_t* keep;
  const double* weights;
  const double* omega2;
  bool weighted;
  Rescale rescale;
  double* scales;
  double* keeps;
};

// Over V lanes of bins from `first` in whole vectors up to `count`; returns where it stopped.
// Companion vector types of a vector of doubles (vector_size cannot depend on a template
// parameter): shuffle selectors of its width, and one byte per lane.
template <std::size_t kBytes>
struct LaneCompanions;
template <>
struct LaneCompanions<16> {
  using Selector = long long __attribute__((vector_size(16)));
  using Bytes = std::uint8_t __attribute__((vector_size(2)));
};
template <>
struct LaneCompanions<64> {
  using Selector = long long __attribute__((vector_size(64)));
  using Bytes = std::uint8_t __attribute__((vector_size(8)));
};

// V lanes of keep bytes (0 or 1) from `keep` as doubles. By reference and inlined: no vector
// crosses a call.
template <class V>
[[gnu::always_inline]] inline void load_keep(const std::uint8_t* keep, V& out) {
  typename LaneCompanions<sizeof(V)>::Bytes bytes;
  std::memcpy(&bytes, keep, sizeof bytes);
  out = __builtin_convertvector(bytes, V);
}

// The lanes' sum: a tree for eight (the order the wide kernels have always summed in).
template <class V>
[[gnu::always_inline]] inline double lane_sum(const V& v) {
  if constexpr (sizeof(V) == 64) {
    return ((v[0] + v[1]) + (v[2] + v[3])) + ((v[4] + v[5]) + (v[6] + v[7]));
  } else {
    return v[0] + v[1];
  }
}

// |X| and X / |X| of V lanes of bins (re, im) stored at `level`, `unit_re`, `unit_im`.
template <class V>
[[gnu::always_inline]] inline void store_units(const V& re, const V& im, double* level,
                                               double* unit_re, double* unit_im) {
  const V power = re * re + im * im;
  V inverse;
  inverse_sqrt(power, inverse);
  const V size = power * inverse;
  const V unit_real = re * inverse;
  const V unit_imag = im * inverse;
  std::memcpy(level, &size, sizeof size);
  std::memcpy(unit_re, &unit_real, sizeof unit_real);
  std::memcpy(unit_im, &unit_imag, sizeof unit_imag);
}

// One pair's rows for pair_products(): unit phasors and levels of its two mics, the bins'
// keep bytes (null: all kept) and weights (null: unweighted), and where the products go.
struct PairRows {
  const double* a_re;
  const double* a_im;
  const double* b_re;
  const double* b_im;
  const double* level_i;
  const double* level_j;
  const std::uint8_t* keep;
  const double* weights;
  double* out;  // (re, im) interleaved
  double* magnitude;
};

// W = u_i u_j* (times live x w) and |G| = |X_i| |X_j| (times live) over V lanes of bins from
// `first` in whole vectors up to `count`; adds the magnitudes (times w) to `magnitude_sum` and
// returns where it stopped. Below kSilentBin a bin carries no phase: zero weight, as when a
// channel is silent. One body for pair_phasors() and wide_pair_products().
template <class V>
[[gnu::always_inline]] inline std::size_t pair_products(const PairRows& rows, std::size_t first,
                                                        std::size_t count, double& magnitude_sum) {
  constexpr std::size_t kLanes = sizeof(V) / sizeof(double);
  using Selector = typename LaneCompanions<sizeof(V)>::Selector;
  const V silent = V{} + kSilentBin;
  const V one = V{} + 1.0;
  const V zero = V{};
  V total{};
  std::size_t n = first;
  for (; n + kLanes <= count; n += kLanes) {
    V ar, ai, br, bi, li, lj;
    std::memcpy(&ar, rows.a_re + n, sizeof ar);
    std::memcpy(&ai, rows.a_im + n, sizeof ai);
    std::memcpy(&br, rows.b_re + n, sizeof br);
    std::memcpy(&bi, rows.b_im + n, sizeof bi);
    std::memcpy(&li, rows.level_i + n, sizeof li);
    std::memcpy(&lj, rows.level_j + n, sizeof lj);
    const V size = li * lj;
    V live = size > silent ? one : zero;
    if (rows.keep != nullptr) {
      V keep;
      load_keep(rows.keep + n, keep);
      live *= keep;
    }
    V w = one;
    if (rows.weights != nullptr) std::memcpy(&w, rows.weights + n, sizeof w);
    const V scale = live * w;
    const V re = (ar * br + ai * bi) * scale;
    const V im = (ai * br - ar * bi) * scale;
    V low, high;  // bins' (re, im) pairs, first and second half of the lanes
    if constexpr (kLanes == 8) {
      low = DRONETRACK_SHUFFLE(re, im, Selector, 0, 8, 1, 9, 2, 10, 3, 11);
      high = DRONETRACK_SHUFFLE(re, im, Selector, 4, 12, 5, 13, 6, 14, 7, 15);
    } else {
      low = DRONETRACK_SHUFFLE(re, im, Selector, 0, 2);
      high = DRONETRACK_SHUFFLE(re, im, Selector, 1, 3);
    }
    const V sizes = size * live;
    std::memcpy(rows.out + 2 * n, &low, sizeof low);
    std::memcpy(rows.out + 2 * n + kLanes, &high, sizeof high);
    std::memcpy(rows.magnitude + n, &sizes, sizeof sizes);
    total += sizes * w;
  }
  magnitude_sum += lane_sum(total);
  return n;
}

template <class V>
[[gnu::always_inline]] inline std::size_t kept_sums(const KeptRows& rows, std::size_t first,
                                                    std::size_t count, KeptSums& out) {
  constexpr std::size_t kLanes = sizeof(V) / sizeof(double);
  V kept_sum{}, w_sum{}, w2_sum{}, omega2_sum{}, w2_omega2_sum{}, omega4_sum{};
  std::size_t n = first;
  for (; n + kLanes <= count; n += kLanes) {
    V keep, w, omega2;
    load_keep(rows.keep + n, keep);
    std::memcpy(&w, rows.weights + n, sizeof w);
    std::memcpy(&omega2, rows.omega2 + n, sizeof omega2);
    const V used = rows.weighted ? w : V{} + 1.0;
    const V kept_w = keep * used;
    kept_sum += keep;
    w_sum += kept_w;
    w2_sum += kept_w * used;
    omega2_sum += kept_w * omega2;
    w2_omega2_sum += kept_w * used * omega2;
    omega4_sum += keep * omega2 * omega2;
    const V scale = rows.rescale == Rescale::none     ? keep
                    : rows.rescale == Rescale::weight ? keep * w
                                                      : keep / w;
    std::memcpy(rows.scales + n, &scale, sizeof scale);
    std::memcpy(rows.keeps + n, &keep, sizeof keep);
  }
  for (std::size_t l = 0; l < kLanes; ++l) {
    out.kept += kept_sum[l];
    out.w += w_sum[l];
    out.w2 += w2_sum[l];
    out.omega2 += omega2_sum[l];
    out.w2_omega2 += w2_omega2_sum[l];
    out.omega4 += omega4_sum[l];
  }
  return n;
}

#if defined(__x86_64__) && defined(__GNUC__)
#define DRONETRACK_WIDE_SIMD 1
// With AVX-512 the lag grid summed directly over the kept bins beats the inverse FFT even over
// the whole band (doa_bench BM_PipelineStage 2 and 4 on a Zen 4: 342 bins x 31 lags x 6 pairs
// in ~6.5 us against ~9 us for six single-precision c2r transforms of 2048 points, and 4x the
// two-lane sums on a masked look): kWideProductsPerFftPoint instead of
// kDirectProductsPerFftPoint. Chosen at run time; other machines keep the two-lane sums.
constexpr double kWideProductsPerFftPoint = 1.0;
constexpr int kWideGroup = 6;  // pairs per pass over the kept bins: 24 accumulators + 4 table

struct WideJob {
  const std::complex<double>* const* phasors;  // kWideGroup rows (unused slots: a zero row)
  double* const* grids;                        // kWideGroup outputs (unused: nullptr)
  const int* half_spans;                       // kWideGroup
  int max_half;                                // largest of half_spans
  const double* lag_table;                     // per band bin: stride cos, then stride sin
  std::size_t stride;
  const int* kept_indices;
  int kept;
  double normalisation;
};

// R(+-m) = (1/K) sum_k (Re W_k cos(w_k m step) -+ Im W_k sin(w_k m step)) for kWideGroup pairs
// at once, 16 lags per block: every table row is loaded once for all the group's pairs.
__attribute__((target("avx512f,fma"))) void wide_direct_grids(const WideJob& job) {
  using Wide = double __attribute__((vector_size(64)));
  constexpr int kBlock = 16;
  for (int first = 0; first <= job.max_half; first += kBlock) {
    Wide cosine_low[kWideGroup] = {};
    Wide cosine_high[kWideGroup] = {};
    Wide sine_low[kWideGroup] = {};
    Wide sine_high[kWideGroup] = {};
    for (int n = 0; n < job.kept; ++n) {
      const auto index = static_cast<std::size_t>(job.kept_indices[n]);
      const double* cosines = job.lag_table + index * 2 * job.stride + first;
      const double* sines = cosines + job.stride;
      Wide c_low, c_high, s_low, s_high;
      std::memcpy(&c_low, cosines, sizeof c_low);
      std::memcpy(&c_high, cosines + 8, sizeof c_high);
      std::memcpy(&s_low, sines, sizeof s_low);
      std::memcpy(&s_high, sines + 8, sizeof s_high);
      for (int q = 0; q < kWideGroup; ++q) {
        const std::complex<double> w = job.phasors[q][index];
        const Wide re = Wide{} + w.real();
        const Wide im = Wide{} + w.imag();
        cosine_low[q] += re * c_low;
        cosine_high[q] += re * c_high;
        sine_low[q] += im * s_low;
        sine_high[q] += im * s_high;
      }
    }
    for (int q = 0; q < kWideGroup; ++q) {
      if (job.grids[q] == nullptr) continue;
      const int half = job.half_spans[q];
      double* grid_values = job.grids[q];
      const int last = std::min(half, first + kBlock - 1);
      for (int m = first; m <= last; ++m) {
        const int lane = m - first;
        const double a = lane < 8 ? cosine_low[q][lane] : cosine_high[q][lane - 8];
        const double b = lane < 8 ? sine_low[q][lane] : sine_high[q][lane - 8];
        grid_values[half + m] = (a - b) * job.normalisation;
        grid_values[half - m] = (a + b) * job.normalisation;
      }
    }
  }
}

// whiten()'s per-mic pass eight bins per vector (same steps as the two-lane loop): returns
// how many bins it did (whole vectors); the caller finishes the rest.
__attribute__((target("avx512f,fma"))) std::size_t wide_units(const std::complex<double>* x,
                                                              const int* fft_bins,
                                                              std::size_t count, double* level,
                                                              double* unit_re, double* unit_im) {
  using Wide = double __attribute__((vector_size(64)));
  using Selector = long long __attribute__((vector_size(64)));
  std::size_t index = 0;
  for (; index + 8 <= count; index += 8) {
    Wide re, im;
    if (fft_bins[index + 7] - fft_bins[index] == 7) {
      // Eight consecutive FFT bins (within one band run): two loads, split re / im.
      Wide first_half, second_half;
      std::memcpy(&first_half, x + fft_bins[index], sizeof first_half);
      std::memcpy(&second_half, x + fft_bins[index] + 4, sizeof second_half);
      re = DRONETRACK_SHUFFLE(first_half, second_half, Selector, 0, 2, 4, 6, 8, 10, 12, 14);
      im = DRONETRACK_SHUFFLE(first_half, second_half, Selector, 1, 3, 5, 7, 9, 11, 13, 15);
    } else {
      for (int l = 0; l < 8; ++l) {
        re[l] = x[fft_bins[index + l]].real();
        im[l] = x[fft_bins[index + l]].imag();
      }
    }
    store_units(re, im, level + index, unit_re + index, unit_im + index);
  }
  return index;
}

// pair_phasors()'s products eight bins per vector: returns how many bins it did.
__attribute__((target("avx512f,fma"))) std::size_t wide_pair_products(const PairRows& rows,
                                                                      std::size_t count,
                                                                      double& magnitude_sum) {
  using Wide = double __attribute__((vector_size(64)));
  return pair_products<Wide>(rows, 0, count, magnitude_sum);
}

// prepare()'s pass over one pair's band eight bins per vector: phasors times `scales` and
// magnitudes times `keeps` (when `scale`), and the sum of the magnitudes (times `weights` when
// given) in eight partial sums. Returns how many bins it did (whole vectors); the caller
// finishes the rest.
__attribute__((target("avx512f,fma"))) std::size_t wide_scale_and_sum(
    std::complex<double>* phasors, double* magnitudes, const double* scales, const double* keeps,
    const double* weights, bool scale, std::size_t count, double& sum) {
  using Wide = double __attribute__((vector_size(64)));
  using Selector = long long __attribute__((vector_size(64)));
  auto* phasor = reinterpret_cast<double*>(phasors);
  Wide total{};
  std::size_t n = 0;
  for (; n + 8 <= count; n += 8) {
    Wide magnitude;
    std::memcpy(&magnitude, magnitudes + n, sizeof magnitude);
    if (scale) {
      Wide factor, keep, low, high;
      std::memcpy(&factor, scales + n, sizeof factor);
      std::memcpy(&keep, keeps + n, sizeof keep);
      std::memcpy(&low, phasor + 2 * n, sizeof low);
      std::memcpy(&high, phasor + 2 * n + 8, sizeof high);
      // Each bin's factor on its (re, im) pair.
      low *= DRONETRACK_SHUFFLE(factor, factor, Selector, 0, 0, 1, 1, 2, 2, 3, 3);
      high *= DRONETRACK_SHUFFLE(factor, factor, Selector, 4, 4, 5, 5, 6, 6, 7, 7);
      magnitude *= keep;
      std::memcpy(phasor + 2 * n, &low, sizeof low);
      std::memcpy(phasor + 2 * n + 8, &high, sizeof high);
      std::memcpy(magnitudes + n, &magnitude, sizeof magnitude);
    }
    if (weights != nullptr) {
      Wide w;
      std::memcpy(&w, weights + n, sizeof w);
      total += magnitude * w;
    } else {
      total += magnitude;
    }
  }
  sum = ((total[0] + total[1]) + (total[2] + total[3])) +
        ((total[4] + total[5]) + (total[6] + total[7]));
  return n;
}

__attribute__((target("avx512f,fma"))) std::size_t wide_kept_sums(const KeptRows& rows,
                                                                  std::size_t count,
                                                                  KeptSums& out) {
  using Wide = double __attribute__((vector_size(64)));
  return kept_sums<Wide>(rows, 0, count, out);
}

bool wide_simd_supported() { return __builtin_cpu_supports("avx512f") != 0; }
#else
bool wide_simd_supported() { return false; }
#endif

// R(tau) = sum Re(W_k e^{j w_k tau}) and its first four derivatives at one lag (r[n] = sum
// w_k^n Re(j^n W_k e^{j w_k tau})), and the |G|-weighted sum with its first two derivatives
// (coherence): one pass over the band (GccPhat::refine_band_limited).
struct TaylorSums {
  double r[5] = {};
  double weighted = 0.0;
  double slope = 0.0;
  double bend = 0.0;
};

// The Taylor sums over V lanes (two or eight bins, or one): each lane adds its bin's
// t = W_k e^{j w_k tau} weighted by w_k^n, and by |G_k| for the coherence sums. One body for
// taylor_sums() and wide_taylor_sums(); inlined into each (by reference: no vector ABI across a
// call).
template <class V>
struct TaylorLanes {
  V sum0{}, weighted{}, sum1{}, sum2{}, slope{}, sum3{}, sum4{}, bend{};
  [[gnu::always_inline]] void add(const V& w_re, const V& w_im, const V& size, const V& rotation_re,
                                  const V& rotation_im, const V& omega) {
    const V t_re = w_re * rotation_re - w_im * rotation_im;
    const V t_im = w_re * rotation_im + w_im * rotation_re;
    const V omega2 = omega * omega;
    sum0 += t_re;
    weighted += size * t_re;
    sum1 -= omega * t_im;
    slope -= omega * size * t_im;
    sum2 -= omega2 * t_re;
    bend -= omega2 * size * t_re;
    sum3 += omega2 * omega * t_im;
    sum4 += omega2 * omega2 * t_re;
  }
};

TaylorSums taylor_sums(const std::vector<BandRun>& runs, double bin_omega,
                       const std::complex<double>* phasor, const double* magnitude, double lag) {
  // Two interleaved phasors (even and odd bins, each advanced by step^2) in real arithmetic,
  // as the two lanes of one vector: half the latency chain through the complex product, two
  // bins per instruction, no complex-multiply NaN checks.
  TaylorLanes<Lanes> lanes;
  TaylorLanes<double> odd;  // each run's odd bin out
  int index = 0;
  Lanes step2_re, step2_im;
  unit_phasor<Lanes>(Lanes{} + 2.0 * bin_omega * lag, step2_re, step2_im);
  const Lanes omega_step{2.0 * bin_omega, 2.0 * bin_omega};
  for (const BandRun& run : runs) {
    Lanes omega{run.first_bin * bin_omega, (run.first_bin + 1) * bin_omega};
    Lanes rotation_re, rotation_im;
    unit_phasor<Lanes>(omega * lag, rotation_re, rotation_im);
    const int bins = run.last_bin - run.first_bin + 1;
    int k = 0;
    for (; k + 2 <= bins; k += 2, index += 2) {
      const Lanes w_re{phasor[index].real(), phasor[index + 1].real()};
      const Lanes w_im{phasor[index].imag(), phasor[index + 1].imag()};
      const Lanes size{magnitude[index], magnitude[index + 1]};
      lanes.add(w_re, w_im, size, rotation_re, rotation_im, omega);
      const Lanes next_re = rotation_re * step2_re - rotation_im * step2_im;
      rotation_im = rotation_re * step2_im + rotation_im * step2_re;
      rotation_re = next_re;
      omega += omega_step;
    }
    if (k < bins) {
      const double w_re = phasor[index].real();
      const double w_im = phasor[index].imag();
      const double rotation_re0 = rotation_re[0];
      const double rotation_im0 = rotation_im[0];
      const double omega0 = omega[0];
      odd.add(w_re, w_im, magnitude[index], rotation_re0, rotation_im0, omega0);
      ++index;
    }
  }
  TaylorSums sums;
  sums.r[0] = lanes.sum0[0] + lanes.sum0[1] + odd.sum0;
  sums.r[1] = lanes.sum1[0] + lanes.sum1[1] + odd.sum1;
  sums.r[2] = lanes.sum2[0] + lanes.sum2[1] + odd.sum2;
  sums.r[3] = lanes.sum3[0] + lanes.sum3[1] + odd.sum3;
  sums.r[4] = lanes.sum4[0] + lanes.sum4[1] + odd.sum4;
  sums.weighted = lanes.weighted[0] + lanes.weighted[1] + odd.weighted;
  sums.slope = lanes.slope[0] + lanes.slope[1] + odd.slope;
  sums.bend = lanes.bend[0] + lanes.bend[1] + odd.bend;
  return sums;
}

#ifdef DRONETRACK_WIDE_SIMD
// taylor_sums() eight bins per vector: lane l holds bin first + l of a run (rotation e^{j w_k
// tau} advanced by step^8), a run's last partial vector has zero phasors in the unused lanes.
__attribute__((target("avx512f,fma"))) TaylorSums wide_taylor_sums(
    const std::vector<BandRun>& runs, double bin_omega, const std::complex<double>* phasor,
    const double* magnitude, double lag) {
  using Wide = double __attribute__((vector_size(64)));
  constexpr int kLanes = 8;
  TaylorLanes<Wide> lanes;
  // The rotations by the polynomial sincos, all lanes at once (no libm call per lane).
  Wide step8_re, step8_im;
  unit_phasor<Wide>(Wide{} + kLanes * bin_omega * lag, step8_re, step8_im);
  const Wide omega_step = Wide{} + kLanes * bin_omega;
  const Wide lane_bins{0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0};
  int index = 0;
  for (const BandRun& run : runs) {
    Wide omega = (lane_bins + run.first_bin) * bin_omega;
    Wide rotation_re, rotation_im;
    unit_phasor<Wide>(omega * lag, rotation_re, rotation_im);
    const int bins = run.last_bin - run.first_bin + 1;
    for (int k = 0; k < bins; k += kLanes, index += kLanes) {
      Wide w_re, w_im, size;
      if (k + kLanes <= bins) {
        // Eight interleaved (re, im) pairs in two vectors, split into reals and imaginaries.
        using Selector = long long __attribute__((vector_size(64)));
        Wide first_half, second_half;
        std::memcpy(&first_half, phasor + index, sizeof first_half);
        std::memcpy(&second_half, phasor + index + 4, sizeof second_half);
        w_re = DRONETRACK_SHUFFLE(first_half, second_half, Selector, 0, 2, 4, 6, 8, 10, 12, 14);
        w_im = DRONETRACK_SHUFFLE(first_half, second_half, Selector, 1, 3, 5, 7, 9, 11, 13, 15);
        std::memcpy(&size, magnitude + index, sizeof size);
      } else {
        for (int l = 0; l < kLanes; ++l) {
          const bool inside = k + l < bins;
          w_re[l] = inside ? phasor[index + l].real() : 0.0;
          w_im[l] = inside ? phasor[index + l].imag() : 0.0;
          size[l] = inside ? magnitude[index + l] : 0.0;
        }
      }
      lanes.add(w_re, w_im, size, rotation_re, rotation_im, omega);
      const Wide next_re = rotation_re * step8_re - rotation_im * step8_im;
      rotation_im = rotation_re * step8_im + rotation_im * step8_re;
      rotation_re = next_re;
      omega += omega_step;
    }
    index -= (kLanes - bins % kLanes) % kLanes;  // back to the next run's first bin
  }
  const auto total = [](const Wide& v) {
    return ((v[0] + v[1]) + (v[2] + v[3])) + ((v[4] + v[5]) + (v[6] + v[7]));
  };
  TaylorSums sums;
  sums.r[0] = total(lanes.sum0);
  sums.r[1] = total(lanes.sum1);
  sums.r[2] = total(lanes.sum2);
  sums.r[3] = total(lanes.sum3);
  sums.r[4] = total(lanes.sum4);
  sums.weighted = total(lanes.weighted);
  sums.slope = total(lanes.slope);
  sums.bend = total(lanes.bend);
  return sums;
}
#endif
}  // namespace

std::vector<BandRun> band_runs(const std::vector<FrequencyBand>& bands, double sample_rate_hz,
                               int fft_size) {
  const int last_usable = fft_size / 2 - 1;
  std::vector<bool> inside(static_cast<std::size_t>(fft_size / 2 + 1), false);
  for (const FrequencyBand& band : bands) {
    const int first =
        std::max(1, static_cast<int>(std::ceil(band.low_hz * fft_size / sample_rate_hz)));
    const int last = std::min(
        last_usable, static_cast<int>(std::floor(band.high_hz * fft_size / sample_rate_hz)));
    for (int k = first; k <= last; ++k) inside[static_cast<std::size_t>(k)] = true;
  }
  std::vector<BandRun> runs;
  for (int k = 1; k <= last_usable; ++k) {
    if (!inside[static_cast<std::size_t>(k)]) continue;
    if (!runs.empty() && runs.back().last_bin == k - 1) {
      runs.back().last_bin = k;
    } else {
      runs.push_back({k, k});
    }
  }
  if (runs.empty())
    throw std::invalid_argument("bands_hz: no FFT bin inside the bands below Nyquist (" +
                                std::to_string(sample_rate_hz / 2.0) + " Hz)");
  return runs;
}

// The inverse transform runs in single precision: its lag grid only locates the peaks (the
// refinement maximises the continuous correlation from the double phasors) and feeds SRP's
// look-ups, where float rounding (~1e-7 of a peak) is far below the noise; the transform is a
// third of the whole-band correlation's cost in double.
struct GccPhat::Inverse {
  fftwf_complex* spectrum = nullptr;  // correlation_size/2 + 1
  float* correlation = nullptr;       // correlation_size
  fftwf_plan plan = nullptr;
};

GccPhat::GccPhat(int fft_size, int frame_length, double sample_rate_hz,
                 const std::vector<FrequencyBand>& bands, std::vector<MicPairSpec> pairs,
                 LagInterpolation interpolation, int oversample)
    : sample_rate_hz_(sample_rate_hz),
      bin_omega_(2.0 * std::numbers::pi * sample_rate_hz / fft_size),
      runs_(band_runs(bands, sample_rate_hz, fft_size)),
      interpolation_(interpolation),
      pairs_(std::move(pairs)),
      inverse_(std::make_unique<Inverse>()) {
  if (pairs_.empty()) throw std::invalid_argument("GccPhat: needs at least one mic pair");
  if (oversample < 1 || oversample > 64)
    throw std::invalid_argument("GccPhat: oversample must be in [1, 64]");
  for (const BandRun& run : runs_) {
    band_bins_ += run.last_bin - run.first_bin + 1;
    for (int k = run.first_bin; k <= run.last_bin; ++k)
      sum_omega2_ += (k * bin_omega_) * (k * bin_omega_);
  }
  // Hann window: neighbouring bins share phase noise (equivalent noise bandwidth 1.5 bins);
  // zero padding beyond the frame interpolates bins further.
  bin_correlation_ = 1.5 * static_cast<double>(fft_size) / frame_length;

  const int top_bin = runs_.back().last_bin;
  correlation_size_ = 2;
  while (correlation_size_ / 2 <= top_bin) correlation_size_ *= 2;
  correlation_size_ *= oversample;
  lag_step_s_ = static_cast<double>(fft_size) / correlation_size_ / sample_rate_hz;

  int max_half_span = 0;
  for (const MicPairSpec& pair : pairs_) {
    if (!(pair.max_lag_s > 0.0))
      throw std::invalid_argument("GccPhat: mic pair " + std::to_string(pair.mic_i) + "-" +
                                  std::to_string(pair.mic_j) + " has zero spacing");
    // One extra grid step so a peak at the physical limit is still a local maximum.
    int half_span = static_cast<int>(std::ceil(pair.max_lag_s / lag_step_s_)) + 1;
    half_span = std::min(half_span, correlation_size_ / 2 - 1);
    half_spans_.push_back(half_span);
    max_half_span = std::max(max_half_span, half_span);
  }
  grid_stride_ = 2 * max_half_span + 1;
  // Kernel table: offsets up to two maximal lags (two sources at opposite ends), 1/8 grid step.
  kernel_step_s_ = lag_step_s_ / 8.0;
  const int kernel_size = 16 * (2 * max_half_span + 2) + 2;
  kernel_table_.resize(static_cast<std::size_t>(kernel_size));
  std::fill(kernel_table_.begin(), kernel_table_.end(), 0.0);
  for (const BandRun& run : runs_) {
    for (int k = run.first_bin; k <= run.last_bin; ++k) {
      // cos(k w n step) for all n by a complex rotation: no trigonometry per entry.
      const std::complex<double> step = std::polar(1.0, k * bin_omega_ * kernel_step_s_);
      std::complex<double> rotation{1.0, 0.0};
      for (double& entry : kernel_table_) {
        entry += rotation.real();
        rotation *= step;
      }
    }
  }
  for (double& entry : kernel_table_) entry /= band_bins_;
  grids_.assign(static_cast<std::size_t>(grid_stride_) * pairs_.size(), 0.0);
  results_.assign(pairs_.size(), PairCorrelation{});
  phasors_.assign(static_cast<std::size_t>(band_bins_) * pairs_.size(), {0.0, 0.0});
  magnitudes_.assign(static_cast<std::size_t>(band_bins_) * pairs_.size(), 0.0);
  magnitude_sums_.assign(pairs_.size(), 0.0);
  keep_.assign(static_cast<std::size_t>(band_bins_), 1);
  saved_keep_.assign(keep_.size(), 1);
  kept_bins_ = band_bins_;
  kept_weight_ = band_bins_;
  effective_bins_ = band_bins_;
  kept_sum_omega2_ = sum_omega2_;
  kept_sum_w2_omega2_ = sum_omega2_;
  weights_.assign(static_cast<std::size_t>(band_bins_), 1.0);

  for (const MicPairSpec& pair : pairs_)
    unit_channels_ = std::max({unit_channels_, pair.mic_i + 1, pair.mic_j + 1});
  unit_re_.assign(static_cast<std::size_t>(unit_channels_) * static_cast<std::size_t>(band_bins_),
                  0.0);
  unit_im_.assign(unit_re_.size(), 0.0);
  corrected_re_.assign(unit_re_.size(), 0.0);
  corrected_im_.assign(unit_re_.size(), 0.0);
  corrected_.assign(static_cast<std::size_t>(unit_channels_), 0);
  phasor_keep_.assign(static_cast<std::size_t>(band_bins_), 1);
  levels_.assign(unit_re_.size(), 0.0);
  for (const BandRun& run : runs_)
    for (int k = run.first_bin; k <= run.last_bin; ++k) band_fft_bins_.push_back(k);
  refined_index_.assign(pairs_.size(), -1);
  refined_ok_.assign(pairs_.size(), 0);
  refined_peaks_.assign(pairs_.size(), GccPeak{});

  // The search only reads 2 * half_span + 1 lags of the correlation_size_ points the inverse
  // FFT makes. When few bins are kept (the re-correlations after a loud source's bins are
  // dropped: typically 10-30 % of the band) the lags are cheaper summed directly over the kept
  // bins: per bin one row of cos and one of sin over lags 0..max_half_span, each product used
  // for +m and -m. Same sums as the inverse FFT, up to rounding. Per frame correlate() takes
  // the cheaper of the two from the count of kept bins (kDirectProductsPerFftPoint, measured).
  lag_rows_ = max_half_span + 1;
  lag_stride_ = (lag_rows_ + kLagStrideMultiple - 1) / kLagStrideMultiple *
                kLagStrideMultiple;  // whole blocks, zeros after
  wide_simd_ = wide_simd_supported();
  max_direct_products_ = direct_products_limit();
  // No table when too few kept bins to correlate at all would already cost more than the FFT.
  if (max_direct_products_ / lag_rows_ >= std::max(1.0, kMinKeptShare * band_bins_)) {
    const std::size_t row = 2 * static_cast<std::size_t>(lag_stride_);
    lag_table_.assign(static_cast<std::size_t>(band_bins_) * row, 0.0);
    // Angles 2 pi k m / N are multiples of 2 pi / N: reduced exactly in integers and looked up.
    std::vector<std::complex<double>> circle(static_cast<std::size_t>(correlation_size_));
    for (int n = 0; n < correlation_size_; ++n)
      circle[static_cast<std::size_t>(n)] =
          std::polar(1.0, 2.0 * std::numbers::pi * n / correlation_size_);
    std::size_t index = 0;
    for (const BandRun& run : runs_) {
      for (int k = run.first_bin; k <= run.last_bin; ++k, index += row) {
        for (int m = 0; m < lag_rows_; ++m) {
          const std::complex<double> turn = circle[static_cast<std::size_t>(
              static_cast<std::int64_t>(k) * m % correlation_size_)];
          lag_table_[index + static_cast<std::size_t>(m)] = turn.real();
          lag_table_[index + static_cast<std::size_t>(lag_stride_ + m)] = turn.imag();
        }
      }
    }
  } else {
    max_direct_products_ = 0.0;
  }
  kept_indices_.assign(static_cast<std::size_t>(band_bins_), 0);
  for (const BandRun& run : runs_)
    for (int k = run.first_bin; k <= run.last_bin; ++k)
      band_omega2_.push_back((k * bin_omega_) * (k * bin_omega_));
  bin_scales_.assign(static_cast<std::size_t>(band_bins_), 1.0);
  zero_phasors_.assign(static_cast<std::size_t>(band_bins_), {0.0, 0.0});
  bin_keeps_.assign(static_cast<std::size_t>(band_bins_), 1.0);
  const std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  inverse_->spectrum = fftwf_alloc_complex(static_cast<std::size_t>(correlation_size_ / 2 + 1));
  inverse_->correlation = fftwf_alloc_real(static_cast<std::size_t>(correlation_size_));
  if (inverse_->spectrum == nullptr || inverse_->correlation == nullptr) throw std::bad_alloc();
  std::fill_n(reinterpret_cast<float*>(inverse_->spectrum), correlation_size_ + 2, 0.0f);
  inverse_->plan = fftwf_plan_dft_c2r_1d(correlation_size_, inverse_->spectrum,
                                         inverse_->correlation, FFTW_MEASURE);
  if (inverse_->plan == nullptr) throw std::runtime_error("GccPhat: FFTW plan failed");
}

double GccPhat::direct_products_limit() const {
#ifdef DRONETRACK_WIDE_SIMD
  const double products_per_fft_point =
      wide_simd_ ? kWideProductsPerFftPoint : kDirectProductsPerFftPoint;
#else
  const double products_per_fft_point = kDirectProductsPerFftPoint;
#endif
  return products_per_fft_point * correlation_size_ *
         std::log2(static_cast<double>(correlation_size_));
}

bool GccPhat::wide_simd_available() { return wide_simd_supported(); }

void GccPhat::set_wide_simd(bool on) {
  wide_simd_ = on && wide_simd_supported();
  // Without a lag table (built in the constructor when direct sums could ever pay) the FFT
  // stays the only way.
  if (!lag_table_.empty()) max_direct_products_ = direct_products_limit();
}

GccPhat::~GccPhat() {
  if (!inverse_ || inverse_->plan == nullptr) return;
  const std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  if (inverse_->plan != nullptr) fftwf_destroy_plan(inverse_->plan);
  fftwf_free(inverse_->spectrum);
  fftwf_free(inverse_->correlation);
}

std::span<const double> GccPhat::grid(int pair) const {
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  return {grids_.data() + static_cast<std::ptrdiff_t>(pair) * grid_stride_,
          static_cast<std::size_t>(2 * half + 1)};
}

std::span<const std::complex<double>> GccPhat::phasors(int pair) const {
  return {phasors_.data() + static_cast<std::ptrdiff_t>(pair) * band_bins_,
          static_cast<std::size_t>(band_bins_)};
}

std::span<const double> GccPhat::magnitudes(int pair) const {
  return {magnitudes_.data() + static_cast<std::ptrdiff_t>(pair) * band_bins_,
          static_cast<std::size_t>(band_bins_)};
}

void GccPhat::save_whitened() { std::copy(keep_.begin(), keep_.end(), saved_keep_.begin()); }

void GccPhat::restore_whitened(bool weighted) {
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  std::copy(saved_keep_.begin(), saved_keep_.end(), keep_.begin());
  // The frame's per-mic units and levels are still here: the pairs' phasors and magnitudes
  // are made again exactly as whiten() made them, the saved mask's dropped bins zero (as
  // correlate() had left them), instead of keeping a copy of every pair's band.
  pair_phasors(true, weighted);
}

std::span<const double> GccPhat::unit_real(int mic) const {
  return {unit_re_.data() + static_cast<std::size_t>(mic) * static_cast<std::size_t>(band_bins_),
          static_cast<std::size_t>(band_bins_)};
}

std::span<const double> GccPhat::unit_imag(int mic) const {
  return {unit_im_.data() + static_cast<std::size_t>(mic) * static_cast<std::size_t>(band_bins_),
          static_cast<std::size_t>(band_bins_)};
}

GccPhat::UnitRows GccPhat::correct_units(int mic) {
  const std::size_t row = static_cast<std::size_t>(mic) * static_cast<std::size_t>(band_bins_);
  const auto bins = static_cast<std::size_t>(band_bins_);
  corrected_[static_cast<std::size_t>(mic)] = 1;
  return {{corrected_re_.data() + row, bins}, {corrected_im_.data() + row, bins}};
}

void GccPhat::uncorrect_units() {
  std::fill(corrected_.begin(), corrected_.end(), std::uint8_t{0});
}

void GccPhat::process(const MultichannelFft& spectra) {
  whiten(spectra);
  correlate();
}

void GccPhat::whiten(const MultichannelFft& spectra) {
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  // W_ij = X_i X_j* / |X_i X_j*| = (X_i / |X_i|) (X_j / |X_j|)*: each channel is normalised
  // once (a square root and a division per bin and mic, not per bin and pair), the pairs are
  // products of unit phasors and |G_ij| = |X_i| |X_j|.
  // Units are kept as separate real and imaginary rows so that every loop below runs two bins
  // per SIMD instruction.
  const auto bins = static_cast<std::size_t>(band_bins_);
  for (int mic = 0; mic < unit_channels_; ++mic) {
    const std::complex<double>* x = spectra.spectrum(mic);
    const std::size_t row = static_cast<std::size_t>(mic) * bins;
    double* unit_re = unit_re_.data() + row;
    double* unit_im = unit_im_.data() + row;
    double* level = levels_.data() + row;
    // One pass per mic, two bins per step: |X|^2, 1/|X|, then |X| = |X|^2 / |X| and the unit
    // X / |X|. A silent bin (X = 0) gets the unit phasor 0.
    std::size_t index = 0;
#ifdef DRONETRACK_WIDE_SIMD
    if (wide_simd_) index = wide_units(x, band_fft_bins_.data(), bins, level, unit_re, unit_im);
#endif
    for (; index + 2 <= bins; index += 2) {
      const std::complex<double> x0 = x[band_fft_bins_[index]];
      const std::complex<double> x1 = x[band_fft_bins_[index + 1]];
      const Lanes re{x0.real(), x1.real()};
      const Lanes im{x0.imag(), x1.imag()};
      store_units(re, im, level + index, unit_re + index, unit_im + index);
    }
    for (; index < bins; ++index) {
      const std::complex<double> x0 = x[band_fft_bins_[index]];
      const double size = std::sqrt(x0.real() * x0.real() + x0.imag() * x0.imag());
      const double inverse = size > 0.0 ? 1.0 / size : 0.0;
      level[index] = size;
      unit_re[index] = x0.real() * inverse;
      unit_im[index] = x0.imag() * inverse;
    }
  }
  uncorrect_units();
  std::fill(keep_.begin(), keep_.end(), std::uint8_t{1});
  pair_phasors(false);
}

void GccPhat::pair_phasors(bool masked, bool weighted) {
  // W_ij = u_i u_j* and |G_ij| = |X_i| |X_j| from whiten()'s per-mic rows; `masked`: bins
  // dropped in keep_ zero; `weighted`: the phasors times the bins' weights, as a weighted
  // prepare() would scale them (the same product: live x w is w or 0).
  const auto bins = static_cast<std::size_t>(band_bins_);
  if (weighted)
    for (double& w : weights_) w = std::clamp(w, kMinWeight, 1.0);
  const double* weights = weighted ? weights_.data() : nullptr;
  for (std::size_t p = 0; p < pairs_.size(); ++p) {
    const auto mic_i = static_cast<std::size_t>(pairs_[p].mic_i);
    const auto mic_j = static_cast<std::size_t>(pairs_[p].mic_j);
    const std::size_t row_i = mic_i * bins;
    const std::size_t row_j = mic_j * bins;
    const double* a_re = (corrected_[mic_i] != 0 ? corrected_re_ : unit_re_).data() + row_i;
    const double* a_im = (corrected_[mic_i] != 0 ? corrected_im_ : unit_im_).data() + row_i;
    const double* b_re = (corrected_[mic_j] != 0 ? corrected_re_ : unit_re_).data() + row_j;
    const double* b_im = (corrected_[mic_j] != 0 ? corrected_im_ : unit_im_).data() + row_j;
    const double* level_i = levels_.data() + row_i;
    const double* level_j = levels_.data() + row_j;
    double* out = reinterpret_cast<double*>(phasors_.data() + p * bins);
    double* magnitude = magnitudes_.data() + p * bins;
    const PairRows rows{
        a_re,    a_im, b_re,     b_im, level_i, level_j, masked ? keep_.data() : nullptr,
        weights, out,  magnitude};
    // In vector lanes (the compiler cannot tell the rows from the output apart, so plain loops
    // stay scalar): eight bins per step on AVX-512, then two, then the odd one out.
    std::size_t n = 0;
    double magnitude_sum = 0.0;
#ifdef DRONETRACK_WIDE_SIMD
    if (wide_simd_) n = wide_pair_products(rows, bins, magnitude_sum);
#endif
    n = pair_products<Lanes>(rows, n, bins, magnitude_sum);
    for (; n < bins; ++n) {
      const double size = level_i[n] * level_j[n];
      const double live =
          (size > kSilentBin ? 1.0 : 0.0) * (masked ? static_cast<double>(keep_[n]) : 1.0);
      const double scale = weighted ? live * weights[n] : live;
      out[2 * n] = (a_re[n] * b_re[n] + a_im[n] * b_im[n]) * scale;
      out[2 * n + 1] = (a_im[n] * b_re[n] - a_re[n] * b_im[n]) * scale;
      magnitude[n] = live * size;
      magnitude_sum += magnitude[n] * (weighted ? weights[n] : 1.0);
    }
    magnitude_sums_[p] = magnitude_sum;
  }
  weights_applied_ = weighted;
  sums_weighted_ = weighted;
  // The mask the phasors now carry: prepare() need not scale them again for it.
  if (masked)
    std::copy(keep_.begin(), keep_.end(), phasor_keep_.begin());
  else
    std::fill(phasor_keep_.begin(), phasor_keep_.end(), std::uint8_t{1});
}

void GccPhat::prepare_phasors(bool weighted) {
  prepare(weighted);
  for (PairCorrelation& result : results_) result = PairCorrelation{};
}

bool GccPhat::prepare(bool weighted) {
  // The phasors carry the weights of the last weighted correlate() until whiten() or
  // restore_whitened() makes them again: a change of mind scales each bin by w or 1 / w.
  const bool rescale = weighted != weights_applied_;
  // Weights change only on plain phasors (bin_weight()): bounded once, as they go on.
  if (rescale && weighted)
    for (double& w : weights_) w = std::clamp(w, kMinWeight, 1.0);
  // Per bin, vectorised: the kept bins' sums and each bin's scale and keep (bin_scales_,
  // bin_keeps_; used below when bins are dropped or the weights change).
  const auto bins = static_cast<std::size_t>(band_bins_);
  const KeptRows rows{keep_.data(),
                      weights_.data(),
                      band_omega2_.data(),
                      weighted,
                      !rescale   ? Rescale::none
                      : weighted ? Rescale::weight
                                 : Rescale::inverse,
                      bin_scales_.data(),
                      bin_keeps_.data()};
  KeptSums totals;
  std::size_t done = 0;
#ifdef DRONETRACK_WIDE_SIMD
  if (wide_simd_) done = wide_kept_sums(rows, bins, totals);
#endif
  done = kept_sums<Lanes>(rows, done, bins, totals);
  for (; done < bins; ++done) {
    const double keep = keep_[done];
    const double w = weighted ? weights_[done] : 1.0;
    const double omega2 = band_omega2_[done];
    totals.kept += keep;
    totals.w += keep * w;
    totals.w2 += keep * w * w;
    totals.omega2 += keep * w * omega2;
    totals.w2_omega2 += keep * w * w * omega2;
    totals.omega4 += keep * omega2 * omega2;
    const double scale = !rescale ? 1.0 : weighted ? weights_[done] : 1.0 / weights_[done];
    bin_scales_[done] = keep * scale;
    bin_keeps_[done] = keep;
  }
  const int kept = static_cast<int>(totals.kept + 0.5);
  const double sum_w = totals.w;
  const double sum_w2 = totals.w2;
  const double sum_omega2 = totals.omega2;
  const double sum_w2_omega2 = totals.w2_omega2;
  const double sum_omega4 = totals.omega4;
  kept_bins_ = kept;
  kept_weight_ = sum_w;
  kept_sum_omega2_ = sum_omega2;
  kept_sum_w2_omega2_ = sum_w2_omega2;
  // An upper bound either way: weights are at most 1.
  taylor_bound_ = runs_.back().last_bin * bin_omega_ * sum_omega4;
  const double effective = sum_w2 > 0.0 ? sum_w * sum_w / sum_w2 : 0.0;
  effective_bins_ = static_cast<int>(effective + 0.5);
  const bool enough_bins = effective >= std::max(1.0, kMinKeptShare * band_bins_);
  if (!enough_bins) {
    kept_bins_ = std::max(kept_bins_, 1);
    effective_bins_ = std::max(effective_bins_, 1);
    kept_weight_ = std::max(kept_weight_, 1.0);
    kept_sum_omega2_ = std::max(kept_sum_omega2_, bin_omega_ * bin_omega_);
    kept_sum_w2_omega2_ = std::max(kept_sum_w2_omega2_, bin_omega_ * bin_omega_);
  }
  std::fill(refined_index_.begin(), refined_index_.end(), -1);
  const bool all_kept = kept == band_bins_;
  // Dropped bins leave the phasors too: refinement and coherence see the kept bins only.
  // Scaling by 0 or 1 instead of a branch per bin (phasors and magnitudes are finite). In the
  // same pass, coherence's total: the magnitude-weighted correlation over the same weights, in
  // four partial sums (one would make every bin wait for the previous addition).
  const auto scale_and_sum = [&]<bool kScale, bool kWeighted>() {
    const double* w = weights_.data();
    const double* scales = bin_scales_.data();
    const double* keeps = bin_keeps_.data();
    for (std::size_t p = 0; p < pairs_.size(); ++p) {
      std::complex<double>* phasor = phasors_.data() + p * static_cast<std::size_t>(band_bins_);
      double* magnitude = magnitudes_.data() + p * static_cast<std::size_t>(band_bins_);
      double sums[4] = {0.0, 0.0, 0.0, 0.0};
      int index = 0;
#ifdef DRONETRACK_WIDE_SIMD
      if (wide_simd_)
        index = static_cast<int>(wide_scale_and_sum(phasor, magnitude, scales, keeps,
                                                    kWeighted ? w : nullptr, kScale,
                                                    static_cast<std::size_t>(band_bins_), sums[0]));
#endif
      for (; index + 4 <= band_bins_; index += 4) {
        for (int lane = 0; lane < 4; ++lane) {
          const int i = index + lane;
          if constexpr (kScale) {
            phasor[i] *= scales[i];
            magnitude[i] *= keeps[i];
          }
          sums[lane] += kWeighted ? magnitude[i] * w[i] : magnitude[i];
        }
      }
      for (; index < band_bins_; ++index) {
        if constexpr (kScale) {
          phasor[index] *= scales[index];
          magnitude[index] *= keeps[index];
        }
        if constexpr (kWeighted) {
          sums[index & 3] += magnitude[index] * w[index];
        } else {
          sums[0] += magnitude[index];
        }
      }
      magnitude_sums_[p] = (sums[0] + sums[1]) + (sums[2] + sums[3]);
    }
  };
  // Dropped bins already zero in the phasors (made under this very mask) need no pass of
  // their own.
  const bool masked_already = std::equal(keep_.begin(), keep_.end(), phasor_keep_.begin());
  const bool scale = (!all_kept && !masked_already) || rescale;
  if (scale) std::copy(keep_.begin(), keep_.end(), phasor_keep_.begin());
  // Phasors made under this mask and weighting (pair_phasors()) came with their sums.
  const bool summed = !scale && masked_already && sums_weighted_ && *sums_weighted_ == weighted;
  if (scale && weighted) scale_and_sum.operator()<true, true>();
  if (scale && !weighted) scale_and_sum.operator()<true, false>();
  if (!scale && !summed && weighted) scale_and_sum.operator()<false, true>();
  if (!scale && !summed && !weighted) scale_and_sum.operator()<false, false>();
  weights_applied_ = weighted;
  sums_weighted_ = weighted;
  enough_bins_ = enough_bins;
  return enough_bins;
}

void GccPhat::correlate(bool refine_peaks, bool weighted) {
  const bool enough_bins = prepare(weighted);
  const double normalisation = 1.0 / kept_weight_;
  const bool direct = static_cast<double>(kept_bins_) * lag_rows_ <= max_direct_products_;
  if (enough_bins && direct) direct_grids(normalisation);
  for (std::size_t p = 0; p < pairs_.size(); ++p) {
    PairCorrelation& result = results_[p];
    result = PairCorrelation{};
    if (!enough_bins) continue;
    const int half = half_spans_[p];
    double* grid_values = grids_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_;
    if (!direct) inverse_grid(p, normalisation, grid_values);

    if (!refine_peaks) continue;
    // Highest and second-highest local maxima on the grid, and the peak_count_ highest.
    int best = -1;
    double best_value = -2.0;
    double second_value = -2.0;
    std::array<int, kMaxGccPeaks> top_index{};
    std::array<double, kMaxGccPeaks> top_value{};
    int top_count = 0;
    for (int m = 0; m < 2 * half + 1; ++m) {
      const double value = grid_values[m];
      const bool left_ok = m == 0 || value >= grid_values[m - 1];
      const bool right_ok = m == 2 * half || value > grid_values[m + 1];
      if (!(left_ok && right_ok)) continue;
      if (value > best_value) {
        second_value = best_value;
        best_value = value;
        best = m;
      } else if (value > second_value) {
        second_value = value;
      }
      if (peak_count_ > 1 && value > 0.0) {
        int position = top_count;
        while (position > 0 && top_value[static_cast<std::size_t>(position - 1)] < value)
          --position;
        if (position >= peak_count_) continue;
        for (int moved = std::min(top_count, peak_count_ - 1); moved > position; --moved) {
          top_index[static_cast<std::size_t>(moved)] =
              top_index[static_cast<std::size_t>(moved - 1)];
          top_value[static_cast<std::size_t>(moved)] =
              top_value[static_cast<std::size_t>(moved - 1)];
        }
        top_index[static_cast<std::size_t>(position)] = m;
        top_value[static_cast<std::size_t>(position)] = value;
        top_count = std::min(top_count + 1, peak_count_);
      }
    }
    result = PairCorrelation{};
    if (best < 0 || !(best_value > 0.0)) continue;
    const double start_lag = (best - half) * lag_step_s_;
    if (!refine(static_cast<int>(p), start_lag, result.peak)) {
      result.peak = {start_lag, best_value};
    }
    const double limit = pairs_[p].max_lag_s + 1.0 / sample_rate_hz_;
    result.peak.lag_s = std::clamp(result.peak.lag_s, -limit, limit);
    result.second_value = std::max(second_value, 0.0);
    result.peak_ratio = result.second_value > result.peak.value / kMaxPeakRatio
                            ? result.peak.value / result.second_value
                            : kMaxPeakRatio;
    result.coherence = result.peak.coherence;
    result.tdoa_variance_s2 = tdoa_variance_for_peak(result.peak.value);
    result.peaks[0] = result.peak;
    result.peak_count = 1;
    // The further peaks (the first is `best`), refined without refine()'s one-per-pair cache,
    // which keeps the main peak's answer for the trackers. Two grid maxima that refine to one
    // peak count once.
    for (int k = 1; k < top_count; ++k) {
      const int m = top_index[static_cast<std::size_t>(k)];
      GccPeak further;
      const bool refined = interpolation_ == LagInterpolation::band_limited
                               ? refine_band_limited(static_cast<int>(p), m, further)
                               : refine_parabolic(static_cast<int>(p), m, further);
      if (!refined) further = {(m - half) * lag_step_s_, top_value[static_cast<std::size_t>(k)]};
      further.lag_s = std::clamp(further.lag_s, -limit, limit);
      if (!(further.value > 0.0)) continue;
      bool distinct = true;
      for (int kept = 0; kept < result.peak_count; ++kept)
        distinct = distinct && std::abs(result.peaks[static_cast<std::size_t>(kept)].lag_s -
                                        further.lag_s) > 0.5 * lag_step_s_;
      if (distinct) result.peaks[static_cast<std::size_t>(result.peak_count++)] = further;
    }
    // Refinement can reorder close values: highest first.
    std::sort(result.peaks.begin() + 1, result.peaks.begin() + result.peak_count,
              [](const GccPeak& a, const GccPeak& b) { return a.value > b.value; });
  }
}

void GccPhat::set_peak_count(int count) {
  if (count < 1 || count > kMaxGccPeaks)
    throw std::invalid_argument("peak count must be in [1, " + std::to_string(kMaxGccPeaks) +
                                "], got " + std::to_string(count));
  peak_count_ = count;
}

void GccPhat::direct_grids(double normalisation) {
  // R(+-m) = (1/K) sum_k (Re W_k cos(w_k m step) -+ Im W_k sin(w_k m step)) over the kept
  // bins. Per pair and block of kLagBlock lags the sums stay in registers over all kept bins.
  // The kept bins' band indices first (only the direct sums use them), without a branch per bin.
  int kept = 0;
  for (int index = 0; index < band_bins_; ++index) {
    kept_indices_[static_cast<std::size_t>(kept)] = index;
    kept += keep_[static_cast<std::size_t>(index)] != 0 ? 1 : 0;
  }
  const auto stride = static_cast<std::size_t>(lag_stride_);
  const auto bins = static_cast<std::size_t>(band_bins_);
#ifdef DRONETRACK_WIDE_SIMD
  if (wide_simd_) {
    for (std::size_t group = 0; group < pairs_.size(); group += kWideGroup) {
      std::array<const std::complex<double>*, kWideGroup> rows{};
      std::array<double*, kWideGroup> grids{};
      std::array<int, kWideGroup> halves{};
      int max_half = 0;
      for (std::size_t q = 0; q < static_cast<std::size_t>(kWideGroup); ++q) {
        const std::size_t p = group + q;
        const bool real_pair = p < pairs_.size();
        rows[q] = real_pair ? phasors_.data() + p * bins : zero_phasors_.data();
        grids[q] =
            real_pair ? grids_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_ : nullptr;
        halves[q] = real_pair ? half_spans_[p] : 0;
        max_half = std::max(max_half, halves[q]);
      }
      wide_direct_grids(WideJob{rows.data(), grids.data(), halves.data(), max_half,
                                lag_table_.data(), stride, kept_indices_.data(), kept_bins_,
                                normalisation});
    }
    return;
  }
#endif
  constexpr int kVectors = kLagBlock / 2;
  for (std::size_t p = 0; p < pairs_.size(); ++p) {
    const std::complex<double>* phasor = phasors_.data() + p * bins;
    const int half = half_spans_[p];
    double* grid_values = grids_.data() + static_cast<std::ptrdiff_t>(p) * grid_stride_;
    for (int first = 0; first <= half; first += kLagBlock) {
      Lanes cosine_sums[kVectors] = {};
      Lanes sine_sums[kVectors] = {};
      for (int n = 0; n < kept_bins_; ++n) {
        const auto index = static_cast<std::size_t>(kept_indices_[static_cast<std::size_t>(n)]);
        const double* cosines = lag_table_.data() + index * 2 * stride + first;
        const double* sines = cosines + stride;
        const Lanes re{phasor[index].real(), phasor[index].real()};
        const Lanes im{phasor[index].imag(), phasor[index].imag()};
        for (int v = 0; v < kVectors; ++v) {
          Lanes c;
          Lanes si;
          std::memcpy(&c, cosines + 2 * v, sizeof c);
          std::memcpy(&si, sines + 2 * v, sizeof si);
          cosine_sums[v] += re * c;
          sine_sums[v] += im * si;
        }
      }
      const int last = std::min(half, first + kLagBlock - 1);
      for (int m = first; m <= last; ++m) {
        const double a = cosine_sums[(m - first) / 2][(m - first) % 2];
        const double b = sine_sums[(m - first) / 2][(m - first) % 2];
        grid_values[half + m] = (a - b) * normalisation;
        grid_values[half - m] = (a + b) * normalisation;
      }
    }
  }
}

void GccPhat::inverse_grid(std::size_t pair, double normalisation, double* grid_values) {
  auto* inverse_bins = reinterpret_cast<float*>(inverse_->spectrum);
  // c2r transforms destroy their input: clear it for every pair.
  std::fill_n(inverse_bins, correlation_size_ + 2, 0.0f);
  const auto* phasor = reinterpret_cast<const double*>(phasors_.data() +
                                                       pair * static_cast<std::size_t>(band_bins_));
  int index = 0;
  for (const BandRun& run : runs_)
    for (int k = 2 * run.first_bin; k <= 2 * run.last_bin + 1; ++k, ++index)
      inverse_bins[k] = static_cast<float>(phasor[index]);
  fftwf_execute(inverse_->plan);
  // The c2r sums both halves of the spectrum: 2 Re(...) per bin.
  const int half = half_spans_[pair];
  const double scale = 0.5 * normalisation;
  for (int m = -half; m <= half; ++m) {
    const int index_circular = m >= 0 ? m : correlation_size_ + m;
    grid_values[m + half] = static_cast<double>(inverse_->correlation[index_circular]) * scale;
  }
}

double GccPhat::tdoa_variance_for_peak(double peak_value) const {
  // A peak value rho = mean_k cos(phase error_k) ~ exp(-sigma_phi^2 / 2): the mean phase-noise
  // variance per bin. A least-squares phase slope through the origin over the band then has
  // variance sigma_phi^2 / sum w_k^2, times the number of bins sharing one independent phase.
  const double rho = std::clamp(peak_value, 0.02, 0.999);
  const double phase_variance = -2.0 * std::log(rho);
  // Weighted: the phase slope through the origin has variance
  // sigma^2 sum w^2 w_k^2 / (sum w w_k^2)^2 (sigma^2 / sum w_k^2 when every w is 1).
  return bin_correlation_ * phase_variance * kept_sum_w2_omega2_ /
         (kept_sum_omega2_ * kept_sum_omega2_);
}

double GccPhat::phat_kernel(double offset_s) const {
  const double position = std::abs(offset_s) / kernel_step_s_;
  const auto below = static_cast<std::size_t>(position);
  if (below + 1 >= kernel_table_.size()) return 0.0;
  const double fraction = position - static_cast<double>(below);
  return kernel_table_[below] * (1.0 - fraction) + kernel_table_[below + 1] * fraction;
}

double GccPhat::value_at(int pair, double lag_s) const {
  const std::complex<double>* phasor =
      phasors_.data() + static_cast<std::size_t>(pair) * static_cast<std::size_t>(band_bins_);
  double sum = 0.0;
  int index = 0;
  const std::complex<double> step = std::polar(1.0, bin_omega_ * lag_s);
  for (const BandRun& run : runs_) {
    std::complex<double> rotation = std::polar(1.0, bin_omega_ * run.first_bin * lag_s);
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      sum += (phasor[index] * rotation).real();
      rotation *= step;
    }
  }
  return sum / kept_weight_;
}

double GccPhat::coherence_at(int pair, double lag_s) const {
  const std::size_t offset = static_cast<std::size_t>(pair) * static_cast<std::size_t>(band_bins_);
  const double total = magnitude_sums_[static_cast<std::size_t>(pair)];
  if (!(total > 0.0)) return 0.0;
  double sum = 0.0;
  int index = 0;
  const std::complex<double> step = std::polar(1.0, bin_omega_ * lag_s);
  for (const BandRun& run : runs_) {
    std::complex<double> rotation = std::polar(1.0, bin_omega_ * run.first_bin * lag_s);
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      sum += magnitudes_[offset + static_cast<std::size_t>(index)] *
             (phasors_[offset + static_cast<std::size_t>(index)] * rotation).real();
      rotation *= step;
    }
  }
  return std::clamp(sum / total, 0.0, 1.0);
}

bool GccPhat::refine(int pair, double start_lag_s, GccPeak& out) const {
  const int m = climb(pair, start_lag_s);
  // The same grid maximum gives the same refined peak: the trackers, the static null and SRP
  // ask again for peaks correlate() already refined.
  const auto p = static_cast<std::size_t>(pair);
  if (refined_index_[p] == m) {
    out = refined_peaks_[p];
    return refined_ok_[p] != 0;
  }
  const bool ok = interpolation_ == LagInterpolation::band_limited
                      ? refine_band_limited(pair, m, out)
                      : refine_parabolic(pair, m, out);
  refined_index_[p] = m;
  refined_peaks_[p] = out;
  refined_ok_[p] = ok ? 1 : 0;
  return ok;
}

int GccPhat::climb(int pair, double start_lag_s) const {
  const std::span<const double> values = grid(pair);
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  int m = static_cast<int>(std::lround(start_lag_s / lag_step_s_)) + half;
  m = std::clamp(m, 0, 2 * half);
  for (int guard = 0; guard < 2 * half + 1; ++guard) {
    if (m > 0 && values[static_cast<std::size_t>(m - 1)] > values[static_cast<std::size_t>(m)]) {
      --m;
    } else if (m < 2 * half &&
               values[static_cast<std::size_t>(m + 1)] > values[static_cast<std::size_t>(m)]) {
      ++m;
    } else {
      break;
    }
  }
  return m;
}

bool GccPhat::refine_parabolic(int pair, int m, GccPeak& out) const {
  refine_parabolic_grid_only(pair, m, out);
  double unused = 0.0;
  evaluate(pair, out.lag_s, unused, out.coherence);
  return true;
}

bool GccPhat::refine_band_limited(int pair, int m, GccPeak& out) const {
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  const double grid_lag_s = (m - half) * lag_step_s_;
  // Start from the parabola through the grid maximum: within a fraction of a grid step, so
  // Newton (quadratic convergence) needs one or two passes over the band.
  GccPeak start;
  refine_parabolic_grid_only(pair, m, start);
  const int found = newton_peak(pair, start.lag_s, grid_lag_s, out);
  if (found < 0) return refine_parabolic(pair, m, out);
  return found > 0;
}

bool GccPhat::refine_from(int pair, double start_lag_s, GccPeak& out) const {
  return enough_bins_ && newton_peak(pair, start_lag_s, start_lag_s, out) > 0;
}

int GccPhat::newton_peak(int pair, double start_lag_s, double anchor_lag_s, GccPeak& out) const {
  double lag = start_lag_s;
  const std::size_t offset = static_cast<std::size_t>(pair) * static_cast<std::size_t>(band_bins_);
  const std::complex<double>* phasor = phasors_.data() + offset;
  const double* magnitude = magnitudes_.data() + offset;
  // R(tau) = sum Re(W_k e^{j w_k tau}); its n-th derivative is sum w_k^n Re(j^n W_k e^{..}).
  // One pass over the band gives R and its first four derivatives at the current lag (and the
  // |G|-weighted sum with two), i.e. R's Taylor polynomial; the peak of that polynomial is
  // found without touching the band again. The polynomial's R' is off by at most
  // |R^(5)| d^4 / 24 <= w_top sum_kept w^4 d^4 / 24 (|W_k| <= 1), so the peak by that over R'':
  // below kNewtonResidual_s the pass was the last (from the parabola's start, typically the
  // first), else the next pass starts from there.
  for (int iteration = 0; iteration < 6; ++iteration) {
#ifdef DRONETRACK_WIDE_SIMD
    const TaylorSums sums = wide_simd_ ? wide_taylor_sums(runs_, bin_omega_, phasor, magnitude, lag)
                                       : taylor_sums(runs_, bin_omega_, phasor, magnitude, lag);
#else
    const TaylorSums sums = taylor_sums(runs_, bin_omega_, phasor, magnitude, lag);
#endif
    const double r0 = sums.r[0];
    const double r1 = sums.r[1];
    const double r2 = sums.r[2];
    const double r3 = sums.r[3];
    const double r4 = sums.r[4];
    if (!(r2 < 0.0)) return -1;
    // Newton on the polynomial's R' = r1 + r2 d + r3 d^2/2 + r4 d^3/6, from the plain step.
    const double reach = 0.5 * lag_step_s_;
    double delta = std::clamp(-r1 / r2, -reach, reach);
    double curvature = r2;
    for (int polish = 0; polish < 4; ++polish) {
      const double slope_at = r1 + delta * (r2 + delta * (0.5 * r3 + delta * r4 / 6.0));
      curvature = r2 + delta * (r3 + 0.5 * delta * r4);
      if (!(curvature < 0.0)) {
        curvature = r2;
        delta = std::clamp(-r1 / r2, -reach, reach);
        break;
      }
      delta = std::clamp(delta - slope_at / curvature, -reach, reach);
    }
    const double delta2 = delta * delta;
    const double residual_s = taylor_bound_ * delta2 * delta2 / (24.0 * std::abs(curvature));
    lag += delta;
    if (residual_s < kNewtonResidual_s || iteration == 5) {
      if (std::abs(lag - anchor_lag_s) > 1.5 * lag_step_s_) return 0;
      const double total = magnitude_sums_[static_cast<std::size_t>(pair)];
      const double value =
          r0 + delta * (r1 + delta * (0.5 * r2 + delta * (r3 / 6.0 + delta * r4 / 24.0)));
      const double coherent = sums.weighted + delta * sums.slope + 0.5 * delta2 * sums.bend;
      out = {lag, value / kept_weight_, total > 0.0 ? std::clamp(coherent / total, 0.0, 1.0) : 0.0};
      return 1;
    }
  }
  return 0;
}

void GccPhat::refine_parabolic_grid_only(int pair, int m, GccPeak& out) const {
  const std::span<const double> values = grid(pair);
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  double offset = 0.0;
  double value = values[static_cast<std::size_t>(m)];
  if (m > 0 && m < 2 * half) {
    const double left = values[static_cast<std::size_t>(m - 1)];
    const double right = values[static_cast<std::size_t>(m + 1)];
    const double curvature = left - 2.0 * value + right;
    if (curvature < 0.0) {
      offset = std::clamp(0.5 * (left - right) / curvature, -0.5, 0.5);
      value -= 0.25 * (left - right) * offset;
    }
  }
  out = {(m - half + offset) * lag_step_s_, value, 0.0};
}

void GccPhat::evaluate(int pair, double lag_s, double& value, double& coherence) const {
  const std::size_t offset = static_cast<std::size_t>(pair) * static_cast<std::size_t>(band_bins_);
  double sum = 0.0;
  double weighted = 0.0;
  int index = 0;
  const std::complex<double> step = std::polar(1.0, bin_omega_ * lag_s);
  for (const BandRun& run : runs_) {
    std::complex<double> rotation = std::polar(1.0, bin_omega_ * run.first_bin * lag_s);
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      const double real = (phasors_[offset + static_cast<std::size_t>(index)] * rotation).real();
      sum += real;
      weighted += magnitudes_[offset + static_cast<std::size_t>(index)] * real;
      rotation *= step;
    }
  }
  value = sum / kept_weight_;
  const double total = magnitude_sums_[static_cast<std::size_t>(pair)];
  coherence = total > 0.0 ? std::clamp(weighted / total, 0.0, 1.0) : 0.0;
}

double GccPhat::grid_value(int pair, double lag_s) const {
  const std::span<const double> values = grid(pair);
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  const double position = lag_s / lag_step_s_ + half;
  if (!(position >= 0.0) || position > 2.0 * half) return 0.0;
  const int below = std::min(static_cast<int>(position), 2 * half - 1);
  const double fraction = position - below;
  return values[static_cast<std::size_t>(below)] * (1.0 - fraction) +
         values[static_cast<std::size_t>(below + 1)] * fraction;
}

int GccPhat::top_peaks(int pair, std::span<GccPeak> out) const {
  const std::span<const double> values = grid(pair);
  const int half = half_spans_[static_cast<std::size_t>(pair)];
  int count = 0;
  for (int m = 0; m < 2 * half + 1; ++m) {
    const double value = values[static_cast<std::size_t>(m)];
    const bool left_ok = m == 0 || value >= values[static_cast<std::size_t>(m - 1)];
    const bool right_ok = m == 2 * half || value > values[static_cast<std::size_t>(m + 1)];
    if (!(left_ok && right_ok) || !(value > 0.0)) continue;
    // Insertion into the descending list of at most out.size().
    int position = count;
    while (position > 0 && out[static_cast<std::size_t>(position - 1)].value < value) --position;
    if (position >= static_cast<int>(out.size())) continue;
    const int last = std::min(count, static_cast<int>(out.size()) - 1);
    for (int moved = last; moved > position; --moved)
      out[static_cast<std::size_t>(moved)] = out[static_cast<std::size_t>(moved - 1)];
    out[static_cast<std::size_t>(position)] = {(m - half) * lag_step_s_, value};
    count = std::min(count + 1, static_cast<int>(out.size()));
  }
  return count;
}

}  // namespace dronetrack::doa
