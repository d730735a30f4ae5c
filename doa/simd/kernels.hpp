#pragma once
// The DSP's vector kernels, written once against Google Highway (doa/simd/kernels.cpp) and
// dispatched at run time to the CPU's best target (doa/simd/dispatch.hpp). Plain functions on plain
// rows: callers never see a vector type. Each kernel does its whole row, tails included.
#include <complex>
#include <cstddef>
#include <cstdint>

#include "doa/band_run.hpp"

namespace dronetrack::doa::simd {

// A row of complex values as two rows, reals and imaginaries: every lane one bin.
struct SplitRows {
  const double* re;
  const double* im;
};
struct SplitOut {
  double* re;
  double* im;
};

// ---- GCC-PHAT ----

// |X|^2, |X| and X / |X| of `count` band bins of one mic's spectrum (X at
// spectrum[fft_bins[n]]); a silent bin (X = 0) gets the unit 0.
struct UnitRows {
  const std::complex<double>* spectrum;
  const int* fft_bins;
  std::size_t count;
  double* power;
  double* level;
  SplitOut unit;
};
void unit_phasors(const UnitRows& rows);

// One pair's phasors W = u_i u_j* (times live x w) and |G| = |X_i| |X_j| (times live); live is
// 0 below `silent_level` (no phase) and for bins with keep 0 (keep null: all kept); weights null:
// unweighted; `given` not null: W is the given phasor (interleaved re, im) normalised to unit
// length (0 stays 0) instead of u_i u_j*. Returns the sum of the magnitudes (times w).
struct PairRows {
  SplitRows a;
  SplitRows b;
  const double* level_i;
  const double* level_j;
  const std::uint8_t* keep;
  const double* weights;
  std::size_t count;
  double silent_level;
  const double* given;
  double* out;        // (re, im) interleaved
  float* out_floats;  // null, or `out` again in single precision (for direct_grids)
  double* magnitude;
};
double pair_products(const PairRows& rows);

// The kept bins' sums of one mask (weights, their squares, w^2 and w^4 terms), and each bin's
// scale (keep times 1, the weight or its inverse) and keep as doubles.
enum class Rescale { none, weight, inverse };
struct KeptRows {
  const std::uint8_t* keep;
  const double* weights;
  const double* omega2;
  std::size_t count;
  bool weighted;
  Rescale rescale;
  double* scales;
  double* keeps;
};
struct KeptSums {
  double kept = 0.0;  // how many bins are kept (sums of 0 and 1: exact)
  double w = 0.0;
  double w2 = 0.0;
  double omega2 = 0.0;
  double w2_omega2 = 0.0;
  double omega4 = 0.0;
};
KeptSums kept_sums(const KeptRows& rows);

// One pair's band: phasors times `scales` and magnitudes times `keeps` (when `scale`); returns
// the sum of the magnitudes (times `weights` when given).
struct ScaleRows {
  double* phasors;       // (re, im) interleaved
  float* phasor_floats;  // null, or the scaled phasors again in single precision
  double* magnitudes;
  const double* scales;
  const double* keeps;
  const double* weights;
  bool scale;
  std::size_t count;
};
double scale_and_sum(const ScaleRows& rows);

// Every pair's lag grid summed directly over the kept bins, in single precision:
// R(+-m) = norm sum_k (Re W_k cos(w_k m step) -+ Im W_k sin(w_k m step)), lags 0..half_span.
// The phasors in single precision come from pair_products and scale_and_sum, which make them;
// only the kept bins' are read.
struct GridJob {
  const float* phasor_floats;  // pair p's band, (re, im) interleaved, at 2 p pair_stride
  std::size_t pair_stride;
  double* grids;  // pair p's 2 half + 1 values at grids + p * grid_stride
  std::size_t grid_stride;
  const int* half_spans;
  int pairs;
  const float* lag_table;  // per band bin: lag_stride cosines, then lag_stride sines
  std::size_t lag_stride;  // a multiple of kLagStrideMultiple
  const int* kept_indices;
  int kept;
  double normalisation;
};
inline constexpr int kLagStrideMultiple = 32;
void direct_grids(const GridJob& job);

// R(tau) = sum Re(W_k e^{j w_k tau}) and its first four derivatives at one lag
// (r[n] = sum w_k^n Re(j^n W_k e^{j w_k tau})), and the |G|-weighted sum with its first two.
struct TaylorRows {
  const BandRun* runs;
  std::size_t run_count;
  double bin_omega;
  const std::complex<double>* phasors;
  const double* magnitudes;
  double lag_s;
};
struct TaylorSums {
  double r[5] = {};
  double weighted = 0.0;
  double slope = 0.0;
  double bend = 0.0;
};
TaylorSums taylor_sums(const TaylorRows& rows);

// ---- ground echo ----

// sum_bins weight |sum_mics aligned conj(c) / |c||^2 with c = 1 + gain echo; row of mic m at
// m * mic_stride; `bins` a multiple of 8 (zero units and weights after the last).
struct CoherenceRows {
  SplitRows aligned;
  SplitRows echo;
  const double* weight;
  std::size_t mics;
  std::size_t mic_stride;
  int bins;
};
double echo_coherence(const CoherenceRows& rows, double gain);

// One mic's units times conj(c) / |c| over the band, c = 1 + level e^{j k phase_step} at FFT
// bin k.
struct CombRows {
  const BandRun* runs;
  std::size_t run_count;
  SplitRows unit;
  SplitOut out;
  double level;
  double phase_step;
};
void comb_divide(const CombRows& rows);

// Per bin (`bins` a multiple of 8) out = level e^{j omega time}, times (in_re + j in_im) when
// given.
struct PhasorRows {
  const double* omega;
  int bins;
  double time_s;
  double level;
  SplitRows in;  // null rows: level e^{j omega time} alone
  SplitOut out;
};
void phasor_rows(const PhasorRows& rows);

// ---- source bin mask ----

// Clears keep[k] of the band bins a source owns: sum_pairs Re(W_pk e^{j w_k tau_p}) at or above
// threshold x scale_k (scales null: 1). Returns how many kept bins it cleared.
struct OwnedBinScan {
  const BandRun* runs;
  std::size_t run_count;
  double bin_omega;
  const std::complex<double>* const* phasors;  // `pairs` rows over the band
  const double* taus;
  int pairs;
  const double* scales;
  double threshold;
  std::uint8_t* keep;
};
int drop_owned_bins(const OwnedBinScan& scan);

// ---- static look ----

// The static look's pairs from phasors averaged over frames, in one pass: per pair the given
// phasor normalised to unit length (0 stays 0) where the bin is live (|X_i| |X_j| above
// `silent_level`, keep 1); then each found source's bins dropped from `keep` (the sum over its
// terms of Re(W_p e^{j w_k tau}) at or above its threshold, as drop_owned_bins unscaled); then
// the phasors times keep x weight and the magnitudes |X_i| |X_j| times keep, with their
// weighted sums. Source s's terms are [source_starts[s], source_starts[s + 1]), at most
// kMaxLookTerms in all.
struct LookRows {
  const BandRun* runs;
  std::size_t run_count;
  double bin_omega;
  int pairs;
  const double* const* given;  // per pair, (re, im) interleaved over the band
  const double* const* level_i;
  const double* const* level_j;
  double silent_level;
  std::uint8_t* keep;     // in: the mask; out: minus the sources' bins
  const double* weights;  // within (0, 1]
  const int* term_pairs;
  const double* term_taus;
  const int* source_starts;  // sources + 1 entries
  int sources;
  const double* thresholds;  // per source
  double* const* out;        // per pair, (re, im) interleaved
  float* const* out_floats;  // per pair, null or `out` again in single precision
  double* const* magnitudes;
  double* magnitude_sums;  // per pair
};
inline constexpr int kMaxLookTerms = 32;
void look_phasors(const LookRows& rows);

// ---- framer ----

// Four interleaved channels' `count` frames into each channel's run (channel c at
// target + c * stride), whole vectors only: returns how many frames it did; adds each channel's
// sum and sum of squares to sums[c] and squares[c] and raises peaks[c] to its largest
// magnitude (one pass serves the framer's checks and the channel health's statistics).
struct FourChannelRows {
  const float* source;
  int count;
  double* target;
  std::ptrdiff_t stride;
  double* sums;
  double* squares;
  double* peaks;
};
int deinterleave_four(const FourChannelRows& rows);

// ---- per-frame statistics (stats_kernels.cpp) ----

// One frame's update of the per-bin SNR (Wiener) weights of BinSnrWeight: smoothed power,
// minimum-tracked noise and weight max(snr / (1 + snr), floor) with
// snr = max(smoothed / (bias noise) - 1, 0), bin by bin (no reduction: the same values as the
// scalar expressions on every target).
struct SnrRows {
  const double* power;
  double* smoothed;
  double* noise;
  double* weights;
  std::size_t count;
  double smoothing;  // share of the old smoothed power
  double rise;       // noise may grow by this factor
  double tiny;       // least noise power
  double bias;       // mean noise over the tracked minimum
  double floor;      // least weight
};
void snr_weights(const SnrRows& rows);

// The value at index count / 2 of values[0, count) sorted (what nth_element picks), by rank
// counting; values finite.
double middle_value(const double* values, int count);

// Per channel of `frames` interleaved frames of `channels` (1..8) floats: the sum, the sum of
// squares and the largest magnitude, in single precision. A NaN sample makes its channel's
// squares NaN (and its peak NaN or not: the caller tests the squares first).
struct InterleavedRows {
  const float* interleaved;
  std::size_t frames;
  int channels;
  float* sums;
  float* squares;
  float* peaks;
};
inline constexpr int kMaxInterleavedChannels = 8;
void channel_sums(const InterleavedRows& rows);

// The acoustic features' bins (AcousticFeatureExtractor): per FFT bin k of [first_bin,
// first_bin + bins) the mics' mean power |X|^2, and the source whose steered sum
// S = sum_m X_m(k) e^{j w_k delay_sm} is the most coherent, |S|^2 >= coherence x mics x sum_m
// |X_m|^2 with coherence from min_coherence up (the first source in order on a tie, as a scalar
// loop over them finds); that source's |S|^2 / mics goes to its row, 0 to every other source's.
struct SteeredBins {
  const std::complex<double>* const* spectra;  // per mic, indexed by FFT bin
  int mics;
  int first_bin;
  int bins;
  double bin_omega;
  const double* delays_s;  // source s, mic m at s * delay_stride + m
  std::size_t delay_stride;
  int sources;  // at most kMaxSteeredSources
  double min_coherence;
  double* mic_power;     // bins
  double* source_power;  // source s's row of `bins` at s * bins
};
inline constexpr int kMaxSteeredSources = 8;
inline constexpr int kMaxSteeredMics = 8;
void steered_bins(const SteeredBins& job);

// average[i] = keep_share x average[i] + (1 - keep_share) x fresh[i] for i < count (the
// static look's phasors averaged over frames: complex rows as pairs of doubles).
struct AverageRows {
  const double* fresh;
  double* average;
  std::size_t count;
  double keep_share;
};
void exponential_average(const AverageRows& rows);

// One pair's agreement with a source at `tdoa_s`, bin by bin over the FFT bins first_bin ..
// first_bin + count - 1 (one run of the band): g = Re(a b* e^{j w_k tdoa}) with a, b the two
// mics' unit rows; where keep is 1, agreement[k] += g and power[k] += magnitude[k] g (the
// steered cross-power), where 0 both unchanged.
struct AgreementRows {
  std::size_t count;
  double first_bin;
  double bin_omega;
  double tdoa_s;
  SplitRows a;
  SplitRows b;
  const double* magnitude;
  const std::uint8_t* keep;
  double* power;
  double* agreement;
};
void steered_agreement(const AgreementRows& rows);

// sum_i a[i] a[i + lag] over i + lag < n, in single precision.
float lagged_product(const float* a, int n, int lag);

}  // namespace dronetrack::doa::simd
