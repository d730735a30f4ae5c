#include "doa/static_source_cancel.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace dronetrack::doa {

StaticSourceCancel::StaticSourceCancel(const GccPhat& gcc, StaticCancelSettings settings)
    : settings_(settings), mics_(gcc.unit_channels()), bins_(gcc.band_bin_count()) {
  if (!(settings_.hop_s > 0.0) || !(settings_.learn_s > 0.0) || settings_.min_updates < 1)
    throw std::invalid_argument("StaticSourceCancel: hop, learning time and updates must be > 0");
  const auto per_bin = static_cast<std::size_t>(mics_);
  const auto bins = static_cast<std::size_t>(bins_);
  covariance_.assign(bins * per_bin * per_bin, {0.0, 0.0});
  steering_.assign(bins * per_bin, {0.0, 0.0});
  updates_.assign(bins, 0);
  spectrum_.assign(per_bin, {0.0, 0.0});
  iterated_.assign(per_bin, {0.0, 0.0});
  cancelled_bins_.assign(bins, 0);
  noise_share_.assign(bins, -1.0);
  if (mics_ >= 3 && mics_ <= kMaxEigenMics) eigen_input_.resize(mics_, mics_);
}

double StaticSourceCancel::noise_residual_share(const std::complex<double>* covariance,
                                                const std::complex<double>* steering) {
  // R has unit trace (every frame enters by its direction alone). Isotropic noise holds the
  // same share in each of its mics_ dimensions and the projection removes one of them. The
  // owner takes the largest eigenvalue; a second steady source (a hovering rotor's line in the
  // same bin) may take the next: the noise per dimension is the mean of the others.
  const auto per_bin = static_cast<std::size_t>(mics_);
  if (mics_ < 3 || mics_ > kMaxEigenMics) {
    double captured = 0.0;  // a^H R a: fall back to everything the owner leaves
    for (std::size_t i = 0; i < per_bin; ++i) {
      std::complex<double> sum{0.0, 0.0};
      for (std::size_t j = 0; j < per_bin; ++j) sum += covariance[i * per_bin + j] * steering[j];
      captured += (std::conj(steering[i]) * sum).real();
    }
    return std::clamp(1.0 - captured, 0.0, 1.0);
  }
  for (int i = 0; i < mics_; ++i)
    for (int j = 0; j < mics_; ++j)
      eigen_input_(i, j) =
          covariance[static_cast<std::size_t>(i) * per_bin + static_cast<std::size_t>(j)];
  eigen_.compute(eigen_input_, Eigen::EigenvaluesOnly);
  if (eigen_.info() != Eigen::Success) return 1.0;  // keep nothing on a failed solve
  // Ascending: the mics_ - 2 smallest are the noise's.
  double noise = 0.0;
  for (int i = 0; i < mics_ - 2; ++i) noise += std::max(0.0, eigen_.eigenvalues()(i));
  return static_cast<double>(mics_ - 1) * noise / (mics_ - 2);
}

void StaticSourceCancel::refill_plane_wave(const std::complex<double>* steering, double residual2,
                                           double bin_power) {
  // Least squares on r_m = |y_m + a_m c|^2 - their mean, Gauss-Newton on (Re c, Im c) from
  // c = 0 (2x2 normal equations): 8 steps, where the noise-free model has converged
  // (scripts/projection-bias.py: A1's error median 0.28 -> 0.04 deg).
  constexpr int kSteps = 8;
  const auto per_bin = static_cast<std::size_t>(mics_);
  double refill_re = 0.0;
  double refill_im = 0.0;
  for (int step = 0; step < kSteps; ++step) {
    double mean_power = 0.0;
    double mean_d_re = 0.0;
    double mean_d_im = 0.0;
    for (std::size_t m = 0; m < per_bin; ++m) {
      const std::complex<double> x =
          spectrum_[m] + steering[m] * std::complex<double>(refill_re, refill_im);
      const std::complex<double> xa = std::conj(x) * steering[m];
      mean_power += std::norm(x);
      mean_d_re += 2.0 * xa.real();   // d|x_m|^2 / d Re c
      mean_d_im += -2.0 * xa.imag();  // d|x_m|^2 / d Im c = 2 Re(conj(x) j a)
    }
    mean_power /= mics_;
    mean_d_re /= mics_;
    mean_d_im /= mics_;
    double jtj00 = 0.0, jtj01 = 0.0, jtj11 = 0.0, jtr0 = 0.0, jtr1 = 0.0;
    for (std::size_t m = 0; m < per_bin; ++m) {
      const std::complex<double> x =
          spectrum_[m] + steering[m] * std::complex<double>(refill_re, refill_im);
      const std::complex<double> xa = std::conj(x) * steering[m];
      const double residual = std::norm(x) - mean_power;
      const double d_re = 2.0 * xa.real() - mean_d_re;
      const double d_im = -2.0 * xa.imag() - mean_d_im;
      jtj00 += d_re * d_re;
      jtj01 += d_re * d_im;
      jtj11 += d_im * d_im;
      jtr0 += d_re * residual;
      jtr1 += d_im * residual;
    }
    const double determinant = jtj00 * jtj11 - jtj01 * jtj01;
    if (!(determinant > 1e-12 * (jtj00 + jtj11) * (jtj00 + jtj11))) break;
    refill_re -= (jtj11 * jtr0 - jtj01 * jtr1) / determinant;
    refill_im -= (jtj00 * jtr1 - jtj01 * jtr0) / determinant;
  }
  // The refilled bin cannot hold more than the bin did before the cancel: a c that would make it
  // louder is no source's (the steps went astray on noise); keep the projection there.
  const double refill2 = refill_re * refill_re + refill_im * refill_im;
  if (!(residual2 + refill2 <= bin_power)) return;
  for (std::size_t m = 0; m < per_bin; ++m)
    spectrum_[m] += steering[m] * std::complex<double>(refill_re, refill_im);
}

void StaticSourceCancel::apply(GccPhat& gcc) {
  cancelled_share_ = 0.0;
  const std::span<std::uint8_t> keep = gcc.bin_keep();
  const GccPhat::UnitsView units = gcc.units();
  const std::span<const double> levels = gcc.band_levels();
  const auto per_bin = static_cast<std::size_t>(mics_);
  // Running mean over the first frames, then an average over ~learn_s (as the null's TDOAs).
  const double max_weight_frames = std::max(1.0, settings_.learn_s / settings_.hop_s);
  int cancelled = 0;
  std::fill(cancelled_bins_.begin(), cancelled_bins_.end(), std::uint8_t{0});
  for (int k = 0; k < bins_; ++k) {
    const auto bin = static_cast<std::size_t>(k);
    if (keep[bin] != 0) continue;
    double norm2 = 0.0;
    for (int m = 0; m < mics_; ++m) {
      const std::size_t index = static_cast<std::size_t>(m) * static_cast<std::size_t>(bins_) + bin;
      spectrum_[static_cast<std::size_t>(m)] =
          levels[index] * std::complex<double>(units.real[index], units.imag[index]);
      norm2 += std::norm(spectrum_[static_cast<std::size_t>(m)]);
    }
    if (!(norm2 > 0.0)) continue;
    // Each frame counts by its direction, not its level: a loud frame must not outvote the
    // steady ones (the bin's level swings by tens of dB with a drone's harmonic passing).
    std::complex<double>* covariance = covariance_.data() + bin * per_bin * per_bin;
    std::complex<double>* steering = steering_.data() + bin * per_bin;
    int& updates = updates_[bin];
    ++updates;
    const double weight = 1.0 / std::min<double>(updates, max_weight_frames);
    // The covariance is Hermitian: its upper triangle is updated and mirrored (an element below
    // the diagonal, x_j x_i* updated alike, is the conjugate of its mirror to the last bit). The
    // products written out as std::complex forms them (x_i x_j* = (ac + bd, bc - ad)), without
    // its check for infinities per product.
    for (std::size_t i = 0; i < per_bin; ++i) {
      const double a = spectrum_[i].real();
      const double b = spectrum_[i].imag();
      for (std::size_t j = i; j < per_bin; ++j) {
        const double c = spectrum_[j].real();
        const double d = spectrum_[j].imag();
        std::complex<double>& upper = covariance[i * per_bin + j];
        const double real = (a * c + b * d) / norm2;
        const double imag = (b * c - a * d) / norm2;
        upper = {upper.real() + weight * (real - upper.real()),
                 upper.imag() + weight * (imag - upper.imag())};
        if (j != i) covariance[j * per_bin + i] = std::conj(upper);
      }
    }
    // One power-iteration step from the last estimate (the first: this frame's vector) follows
    // the leading eigenvector as the average settles.
    if (updates == 1)
      for (std::size_t i = 0; i < per_bin; ++i) steering[i] = spectrum_[i] / std::sqrt(norm2);
    double iterated_norm2 = 0.0;
    for (std::size_t i = 0; i < per_bin; ++i) {
      std::complex<double> sum{0.0, 0.0};
      for (std::size_t j = 0; j < per_bin; ++j) sum += covariance[i * per_bin + j] * steering[j];
      iterated_[i] = sum;
      iterated_norm2 += std::norm(sum);
    }
    if (!(iterated_norm2 > 0.0)) continue;
    const double scale = 1.0 / std::sqrt(iterated_norm2);
    for (std::size_t i = 0; i < per_bin; ++i) steering[i] = iterated_[i] * scale;
    if (updates < settings_.min_updates) continue;
    // x - a (a^H x): what is left of the bin with its owner cancelled.
    std::complex<double> along{0.0, 0.0};
    for (std::size_t i = 0; i < per_bin; ++i) along += std::conj(steering[i]) * spectrum_[i];
    double residual2 = 0.0;
    for (std::size_t i = 0; i < per_bin; ++i) {
      spectrum_[i] -= along * steering[i];
      residual2 += std::norm(spectrum_[i]);
    }
    if (residual2 < settings_.min_residual_share * norm2) continue;
    // The noise's share moves with the covariance's ~learn_s average: solved again every
    // kNoiseRefreshFrames frames of the bin (staggered over the bins), not every frame.
    double& noise_share = noise_share_[bin];
    if (noise_share < 0.0 || (updates + k) % kNoiseRefreshFrames == 0)
      noise_share = noise_residual_share(covariance, steering);
    if (residual2 < settings_.min_residual_over_noise * noise_share * norm2) continue;
    if (settings_.refill_plane_wave) refill_plane_wave(steering, residual2, norm2);
    gcc.set_bin_spectrum(k, spectrum_);
    keep[bin] = 1;
    cancelled_bins_[bin] = 1;
    ++cancelled;
  }
  if (cancelled == 0) return;
  cancelled_share_ = static_cast<double>(cancelled) / bins_;
  // Only the cancelled bins' pair products changed: the rest stay whiten()'s.
  gcc.remake_bins(cancelled_bins_);
}

}  // namespace dronetrack::doa
