#pragma once
// GCC-PHAT for every mic pair (SPEC 4.1): cross-spectrum X_i X_j*, PHAT weight inside the band
// mask, zero outside, inverse FFT on a lag grid limited to the physical lag |tau| <= |p_i-p_j|/c,
// sub-sample refinement and peak quality.
//
// The inverse FFT is short: the band-limited correlation is fully described by samples at
// a rate a little above twice the band's top frequency, so the c2r size is the smallest power of
// two above 2 * top bin (times `oversample`), not the analysis FFT size. Sub-sample refinement
// then maximises the continuous band-limited correlation R(tau) = sum_k Re(W_k e^{j w_k tau})
// directly (Newton steps on the band bins): no interpolation bias at all. Parabolic
// interpolation on the grid is kept for comparison (tests/doa/gcc_phat_test.cpp measures both).
// Only the lags within the physical limit are used: they are summed directly over the kept
// bins (single precision, as the FFT) when that is cheaper than the FFT: with few bins kept (a
// louder source's bins dropped) always, over the whole band when the vectors are wide enough.
//
// Sign convention: tau_ij = t_i - t_j (arrival time at mic i minus at mic j); the correlation
// of X_i X_j* peaks there.
#include <array>
#include <complex>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "doa/band_run.hpp"
#include "doa/doa_params.hpp"
#include "doa/spectral_frame.hpp"

namespace dronetrack::doa {

// The union of `bands` as runs of FFT bins within [1, fft_size/2 - 1], sorted and merged.
// Throws std::invalid_argument when no bin falls inside any band.
std::vector<BandRun> band_runs(const std::vector<FrequencyBand>& bands, double sample_rate_hz,
                               int fft_size);

struct MicPairSpec {
  int mic_i = 0;
  int mic_j = 1;
  double max_lag_s = 0.0;  // |p_i - p_j| / c
};

struct GccPeak {
  double lag_s = 0.0;
  double value = 0.0;      // normalised correlation: 1 = every band bin in phase
  double coherence = 0.0;  // |G|-weighted correlation: the in-band power share coherent here
};

// Most refined peaks a pair keeps per frame (GccPhat::set_peak_count; seed 004's top K = 4).
inline constexpr int kMaxGccPeaks = 4;

// Per pair, per frame.
struct PairCorrelation {
  GccPeak peak;                 // refined highest peak within the physical lag
  double second_value = 0.0;    // highest other local maximum on the grid
  double peak_ratio = 0.0;      // peak / second (capped at 100)
  double coherence = 0.0;       // |G|-weighted correlation at the peak: coherent power share
  double tdoa_variance_s2 = 0;  // from the phase noise implied by the peak value
  // The strongest distinct local maxima, refined like `peak`, highest first (peaks[0] is
  // `peak`); set_peak_count() of them at most.
  std::array<GccPeak, kMaxGccPeaks> peaks{};
  int peak_count = 0;
};

// Found sources whose bins a look on given phasors drops as it makes them (cross_power_from();
// SourceBinMask::add_owner() fills it): source s owns a bin when the sum over its terms (a pair
// and its TDOA) of Re(W_p e^{j w_k tau_p}) reaches thresholds[s].
struct BinOwners {
  static constexpr int kMaxTerms = 32;
  static constexpr int kMaxSources = 8;
  std::array<int, kMaxTerms> pairs{};
  std::array<double, kMaxTerms> taus_s{};
  std::array<int, kMaxSources + 1> starts{};  // source s's terms [starts[s], starts[s + 1])
  std::array<double, kMaxSources> thresholds{};
  int sources = 0;
};

class GccPhat {
 public:
  GccPhat(int fft_size, int frame_length, double sample_rate_hz,
          const std::vector<FrequencyBand>& bands, std::vector<MicPairSpec> pairs,
          LagInterpolation interpolation = LagInterpolation::band_limited, int oversample = 2);
  ~GccPhat();
  GccPhat(const GccPhat&) = delete;
  GccPhat& operator=(const GccPhat&) = delete;

  // Cross-spectra and correlations of every pair from the channel spectra of one frame:
  // whiten() then correlate() with every band bin kept.
  void process(const MultichannelFft& spectra);
  // The two halves of process(), for a per-bin mask in between (StaticSourceNull):
  // whiten() computes every pair's PHAT phasors over the band and keeps every bin;
  // bin_keep() may then clear bins (for all pairs); correlate() drops them, normalises by the
  // bins kept and runs the inverse FFTs and peak refinement.
  void whiten(const MultichannelFft& spectra);
  // refine_peaks false: the lag grid only (pair() results left empty), for a correlation that
  // is only searched (SRP) and refined where asked (refine()). weighted: the phasors carry
  // bin_weight() (normalised by the weights' sum); false: every kept bin counts the same
  // (plain PHAT).
  void correlate(bool refine_peaks = true, bool weighted = true);

  // The band's bins, in the order of phasors()/bin_keep(): runs of FFT bins, ascending.
  const std::vector<BandRun>& band() const { return runs_; }
  int band_bin_count() const { return band_bins_; }
  double bin_omega_rad_per_s() const { return bin_omega_; }
  // PHAT phasors W_k = G_k/|G_k| of one pair over the band bins (after whiten()).
  std::span<const std::complex<double>> phasors(int pair) const;
  // |G_k| of one pair over the band bins (after whiten()).
  std::span<const double> magnitudes(int pair) const;
  // 1 = bin used by correlate(), 0 = dropped for every pair. whiten() sets all to 1.
  std::span<std::uint8_t> bin_keep() {
    prepared_ = false;  // the caller may drop bins: the next correlation applies them
    return keep_;
  }
  std::span<const std::uint8_t> bin_keep() const { return keep_; }
  // Per band bin weight in (0, 1] (order of bin_keep()) that a weighted correlate() puts on the
  // phasors: an SNR weight (BinSnrWeight) so bins with only noise do not dilute the correlation.
  // All 1 (plain PHAT) unless set; kept across frames. Set them while the phasors are plain:
  // after whiten(), an unweighted cross_power() or an unweighted correlate().
  std::span<double> bin_weight() {
    prepared_ = false;
    return weights_;
  }
  std::span<const double> bin_weight() const { return weights_; }
  // What each band bin's phasors are scaled by now: its weight after a weighted correlate(),
  // else 1 (SourceBinMask judges phases, whatever the weight).
  double phasor_scale(int band_index) const {
    return weights_applied_ ? weights_[static_cast<std::size_t>(band_index)] : 1.0;
  }
  // All of them: bin_weight() after a weighted correlate(), else empty (every scale 1).
  std::span<const double> phasor_scales() const {
    return weights_applied_ ? std::span<const double>(weights_) : std::span<const double>();
  }
  // Effective number of band bins in the last correlate(): (sum w)^2 / sum w^2 over the kept
  // bins (the kept-bin count when unweighted).
  int kept_bin_count() const { return effective_bins_; }
  // whiten()'s unit phasors X / |X| of every mic over the band bins: the frame's whitening,
  // unchanged until the next whiten(). A stage that corrects the mics' phases (GroundEcho) takes
  // this view and returns a corrected one over its own rows.
  struct UnitsView {
    const double* real = nullptr;  // mic m's row at m * bins
    const double* imag = nullptr;
    int bins = 0;
    std::span<const double> real_row(int mic) const {
      return {real + static_cast<std::size_t>(mic) * static_cast<std::size_t>(bins),
              static_cast<std::size_t>(bins)};
    }
    std::span<const double> imag_row(int mic) const {
      return {imag + static_cast<std::size_t>(mic) * static_cast<std::size_t>(bins),
              static_cast<std::size_t>(bins)};
    }
  };
  UnitsView units() const;
  // whiten()'s |X|^2 of every mic over the band bins (mic m's row at m * band bins, mics
  // 0..unit_channels() - 1): the frame's in-band powers, for stages that would otherwise read
  // the spectra again (BinSnrWeight, the node's in-band level).
  std::span<const double> band_powers() const { return powers_; }
  // whiten()'s |X| of every mic over the band bins, as band_powers() (a cross-power's level
  // |X_i| |X_j| without a square root per bin).
  std::span<const double> band_levels() const { return levels_; }
  int unit_channels() const { return unit_channels_; }
  // Rewrites whiten()'s unit and level of every mic in one band bin from the given spectrum (mic
  // order): a stage that changes the frame's spectra in place (StaticSourceCancel's projection).
  // band_powers() stays whiten()'s (the in-band level and the channels' health are the mics'
  // own); the pairs see the change at the next cross_power().
  void set_bin_spectrum(int band_index, std::span<const std::complex<double>> spectrum);
  // Every pair's phasor and magnitude of the band bins flagged in `changed` (order of
  // bin_keep()) made again from the units and levels, as whiten() made them (no mask, no
  // weights): after set_bin_spectrum() on a few bins, the rest of the band's products stay.
  // Only while the phasors are whiten()'s (no cross-power or correlation since: std::logic_error
  // otherwise); the next correlation applies bin_keep() and the weights to them as to the rest.
  void remake_bins(std::span<const std::uint8_t> changed);
  std::span<const double> unit_real(int mic) const { return units().real_row(mic); }
  std::span<const double> unit_imag(int mic) const { return units().imag_row(mic); }
  // The band-limited cross-power of every pair from the given units under the given mask:
  // W_ij = u_i u_j* and |G_ij| = |X_i| |X_j| (whiten()'s levels), the mask's dropped bins zero,
  // times bin_weight() when `weighted`. bin_keep() becomes `keep`. whiten() does this with its
  // own units and every bin kept; a frame is correlated again under another mask (several
  // sources: each measured without the others' bins) or on corrected units by calling it again.
  void cross_power(const UnitsView& units, std::span<const std::uint8_t> keep,
                   bool weighted = false);
  // cross_power() of whiten()'s units under `keep`, unweighted, but every live bin's phasor the
  // given one normalised to unit length (0 stays 0) instead of u_i u_j*: pair p's band bins at
  // p * band bins. For a look on phasors averaged over frames (StaticSourceLook); the
  // magnitudes and which bins are live stay the frame's.
  void cross_power_from(std::span<const std::complex<double>> given_phasors,
                        std::span<const std::uint8_t> keep);
  // The same, then the owners' bins dropped from `keep` (SourceBinMask::drop() on the
  // normalised phasors, one source after another) and the phasors weighted (bin_weight(), as a
  // weighted correlate() would scale them), in one pass: the same phasors, magnitudes and mask
  // as cross_power_from(), the drops and the weighted correlate()'s scaling make, bit for bit.
  void cross_power_from(std::span<const std::complex<double>> given_phasors,
                        std::span<const std::uint8_t> keep, const BinOwners& owners);

  // Turns one bin's phasor of one pair to the direction of `cross_power` (its magnitude, the
  // bin's weight, kept; a dropped bin stays 0): for a cross-power corrected after
  // cross_power() (subtract_neighbour_cross_power()). The next correlation or refinement sees it.
  void redirect_phasor(int pair, int band_index, std::complex<double> cross_power);

  int pair_count() const { return static_cast<int>(pairs_.size()); }
  const MicPairSpec& pair_spec(int pair) const { return pairs_[static_cast<std::size_t>(pair)]; }
  const PairCorrelation& pair(int pair) const { return results_[static_cast<std::size_t>(pair)]; }

  // The lag grid of the correlation: lags m * lag_step_s() for m in [-half_span, half_span].
  double lag_step_s() const { return lag_step_s_; }
  int half_span(int pair) const { return half_spans_[static_cast<std::size_t>(pair)]; }
  // Grid values of one pair, 2 * half_span + 1 of them, index 0 = lag -half_span.
  std::span<const double> grid(int pair) const;
  // Linear interpolation on the grid (for SRP look-ups); 0 outside the grid.
  double grid_value(int pair, double lag_s) const;

  // Continuous band-limited correlation at any lag.
  double value_at(int pair, double lag_s) const;
  // Climbs the grid from `start_lag_s` to a local maximum and refines it (Newton on the
  // continuous correlation, or parabolic on the grid, per the interpolation chosen). The last
  // answer per pair is kept until the next whiten()/correlate()/cross_power(): asking
  // again for a peak already refined (trackers, static null, SRP) costs a grid climb.
  bool refine(int pair, double start_lag_s, GccPeak& out) const;
  // The peak near `start_lag_s` by Newton steps on the continuous correlation alone (no grid,
  // band-limited refinement only): within 1.5 grid steps of the start, else false. For a peak
  // known to have moved little (a small phase correction). Applies the current mask and
  // weighting first when no correlation has since they changed.
  bool refine_from(int pair, double start_lag_s, GccPeak& out);
  // How many of each pair's strongest local maxima correlate() refines into pair().peaks, in
  // [1, kMaxGccPeaks]; 1 (the default) costs nothing beyond the main peak. Each further peak
  // costs a refinement (a few passes over the band) per pair and correlate().
  void set_peak_count(int count);
  int peak_count() const { return peak_count_; }
  // Local maxima on the grid, highest first, at most out.size(); returns how many.
  int top_peaks(int pair, std::span<GccPeak> out) const;
  // |G|-weighted correlation at a lag: the share of the in-band power coherent at that lag.
  double coherence_at(int pair, double lag_s) const;
  // The correlation a single ideal source puts at `offset_s` from its own lag (peak 1): the
  // PHAT-whitened band's autocorrelation, (1/K) sum_k cos(w_k offset). Tabulated; used to
  // subtract found sources before looking for the next (SrpPhat).
  double phat_kernel(double offset_s) const;
  // Phase-noise TDOA variance for a given normalised peak value (exposed for the trackers).
  double tdoa_variance_for_peak(double peak_value) const;

 private:
  struct Inverse;
  // Highest, second and the peak_count_ highest local maxima of one pair's grid, refined into
  // pair(p).
  void search_peaks(std::size_t pair);
  int climb(int pair, double start_lag_s) const;  // grid index of the local max uphill
  bool refine_band_limited(int pair, int grid_index, GccPeak& out) const;
  // The Taylor-polynomial Newton passes of refine_band_limited() from `start_lag_s`; false when
  // R is not concave there or the peak ends farther than 1.5 grid steps from `anchor_lag_s`:
  // 1 found, 0 out of reach, -1 R not concave at the start.
  int newton_peak(int pair, double start_lag_s, double anchor_lag_s, GccPeak& out) const;
  // correlate()'s first half (mask, weights, normalisation on the phasors); false when too few
  // bins are kept for a correlation.
  bool prepare(bool weighted);
  bool refine_parabolic(int pair, int grid_index, GccPeak& out) const;
  void refine_parabolic_grid_only(int pair, int grid_index, GccPeak& out) const;
  void evaluate(int pair, double lag_s, double& value, double& coherence) const;
  // given: phasors to normalise in place of u_i u_j* (cross_power_from()), else null.
  void pair_phasors(const UnitsView& units, bool masked, bool weighted,
                    const std::complex<double>* given = nullptr);
  void direct_grids(double normalisation);
  void inverse_grid(std::size_t pair, double normalisation, double* grid_values);

  double sample_rate_hz_;
  int fft_size_;
  double bin_omega_;  // rad/s per bin
  std::vector<BandRun> runs_;
  int band_bins_ = 0;
  double sum_omega2_ = 0.0;  // sum of w_k^2 over band bins
  // This frame's kept bins (all band bins unless a mask dropped some): normalisation of the
  // correlation and the TDOA variance.
  int kept_bins_ = 0;
  double kept_weight_ = 0.0;  // sum of the kept bins' weights (kept_bins_ unweighted): R's scale
  int effective_bins_ = 0;
  double kept_sum_omega2_ = 0.0;     // sum_kept w w_k^2
  double kept_sum_w2_omega2_ = 0.0;  // sum_kept w^2 w_k^2
  std::vector<double> weights_;      // bin_weight()
  bool weights_applied_ = false;     // the phasors carry weights_ (last correlate() weighted)
  bool enough_bins_ = false;         // the last prepare() kept enough bins for a correlation
  bool prepared_ = false;  // prepare() has run since the phasors, mask or weights last changed
  bool whitened_ = false;  // the phasors are whiten()'s, unmasked and unweighted (remake_bins())
  std::vector<std::uint8_t> keep_;         // per band bin
  std::vector<std::uint8_t> phasor_keep_;  // the mask the phasors carry (its dropped bins zero)
  double taylor_bound_ = 0.0;              // w_top sum_kept w^4: bounds the fifth derivative of R
  double bin_correlation_ = 1.0;  // how many bins share one independent phase (window, padding)
  LagInterpolation interpolation_;
  int peak_count_ = 1;
  std::vector<MicPairSpec> pairs_;
  std::vector<int> half_spans_;
  std::vector<PairCorrelation> results_;
  int correlation_size_ = 0;
  double lag_step_s_ = 0.0;
  // Per pair: PHAT phasors W_k and |G_k| over the band bins (concatenated runs).
  std::vector<std::complex<double>> phasors_;
  std::vector<double> magnitudes_;
  std::vector<double> magnitude_sums_;
  // How magnitude_sums_ were summed last (weighted or not): with the magnitudes they belong to.
  std::optional<bool> sums_weighted_;
  // whiten(): per mic over the band bins, X / |X| (real and imaginary rows) and |X|.
  int unit_channels_ = 0;
  std::vector<double> unit_re_;
  std::vector<double> unit_im_;
  std::vector<double> levels_;
  std::vector<double> powers_;        // |X|^2, as levels_
  std::vector<int> band_fft_bins_;    // FFT bin of each band bin
  std::vector<double> band_omega2_;   // w_k^2 of each band bin
  std::vector<double> kernel_table_;  // phat_kernel at multiples of kernel_step_s_ from 0
  double kernel_step_s_ = 0.0;
  std::vector<double> grids_;  // per pair, 2 * max_half_span + 1
  int grid_stride_ = 0;
  // Lag grid summed directly over the kept bins (direct_grids) or by the inverse FFT.
  int lag_rows_ = 0;    // lags 0..max half span
  int lag_stride_ = 0;  // lag_rows_ rounded up to whole blocks
  // Per band bin: lag_stride_ values of cos, then of sin, of w_k m lag_step for lags m
  // (single precision, as the sums over them).
  std::vector<float> lag_table_;
  // The phasors in single precision for direct_grids(), made with them (pair_products,
  // scale_and_sum): each demoted once, not once per correlation (empty without direct sums).
  // Only the kept bins' values are read: a dropped bin's may be stale (prepare() rewrites them
  // only when the weights change; a mask change leaves the kept bins' values as they were).
  std::vector<float> phasor_floats_;
  float* phasor_floats(std::size_t pair) {
    return phasor_floats_.empty()
               ? nullptr
               : phasor_floats_.data() + 2 * pair * static_cast<std::size_t>(band_bins_);
  }
  std::vector<int> kept_indices_;     // band indices of the kept bins (direct_grids())
  std::vector<double> bin_scales_;    // correlate(): per band bin, keep x (w, 1 / w or 1)
  std::vector<double> bin_keeps_;     // correlate(): per band bin, keep as 0 or 1
  double max_direct_products_ = 0.0;  // kept bins x lag_rows_ up to which direct is cheaper
  std::unique_ptr<Inverse> inverse_;
  // refine()'s last answer per pair (grid index, -1 none): valid until the phasors or the grid
  // change. Makes refine() not safe to call concurrently on one GccPhat.
  mutable std::vector<int> refined_index_;
  mutable std::vector<GccPeak> refined_peaks_;
  mutable std::vector<std::uint8_t> refined_ok_;
};

}  // namespace dronetrack::doa
