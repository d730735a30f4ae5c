#pragma once
// Static-source cancellation (doa.static_null_cancel): where the static null (StaticSourceNull)
// drops the band bins a learned ground source owns, keep them with that source projected out.
// A drone 2-8 dB under a generator in its own comb bins loses those bins to the null's drop;
// the generator's spatial signature in each bin is steady (it does not move), so it can be
// cancelled there instead: each bin's mic vector x is replaced by P x, P = I - a a^H, a the unit
// steering vector of the bin's owner, and the drone's share of the bin survives.
//
// The steering vector is learned per bin, not modelled: the principal eigenvector of the bin's
// spatial covariance averaged over the frames the null gave the bin to a static source (one
// power-iteration step a frame from the last estimate). A generator 5 m away is in the near
// field and its own ground reflection bends its phases; the covariance carries both, a plane-wave
// model neither. A moving source in the same bins turns its phases from frame to frame and
// averages out of the covariance's leading direction.
//
// Localising on P x: for a source with steering vector b the projected data is P b. Its pair
// cross-spectra hold b_i b_j* at half weight, plus terms whose phase wanders with frequency, so
// the pair correlations peak near the source's lags, but not on them: with four mics |a^H b|^2
// stays near 1/4 at any separation, and the lost a (a^H b) bends each pair's phase in each bin
// (ground-interferer A1, no noise: a median 0.28 deg). So the kept bins are refilled with the
// a c that makes the mics' moduli equal again (a far source's plane wave: b itself when only
// b and the owner are in the bin), and every later stage (GCC peaks, SRP looks, re-measures,
// ground echoes) runs unchanged on them (docs/doa.md, stage 3c and "A1 beside the generator").
// The premise's limit: a drone's own ground echo makes its moduli differ between mics at
// different heights, and the refill then adds back the wrong component (with the echo the
// noise-free model's A1 error is 0.39 deg, not 0.04: docs/doa.md "What is left at A1").
//
// Per frame: apply() right after StaticSourceNull::mask(), before any correlation. Everything is
// sized in the constructor; nothing is allocated per frame.
#include <complex>
#include <cstdint>
#include <vector>

#include <Eigen/Eigenvalues>

#include "doa/gcc_phat.hpp"

namespace dronetrack::doa {

struct StaticCancelSettings {
  double hop_s = 0.05;   // time between frames
  double learn_s = 3.0;  // the covariance's averaging time (the null's learning time)
  int min_updates = 10;  // frames a bin must have been owned before it is cancelled
  // A cancelled bin is kept only when what the projection leaves holds this share of the bin's
  // power: with the owner alone in it, noise and the steering vector's error leave a few percent,
  // which PHAT would lift to a full bin's weight of noise in every correlation.
  double min_residual_share = 0.1;
  // ... and at least this multiple of the share the bin's noise leaves: (mics - 1) x the noise's
  // share per mic dimension, the mean of the learned covariance's eigenvalues but the two largest
  // (the owner's and one more steady source's, a hovering rotor's line in the same bin). A
  // residual no larger than the noise's is noise; 2 keeps a bin only when something else holds at
  // least as much power as the noise there (0 dB). Without it an array far from the owner, where
  // the owner stands only a few dB over the ambient noise in its bins, keeps them on their noise.
  double min_residual_over_noise = 2.0;
  // Refill each kept bin's component along the steering vector a (what the projection took from
  // the other sources too): P b is not a steering vector, its pairs' phases are bent by
  // -a (a^H b) (a 4-mic array's sidelobes put |a^H b|^2 near 1/4 at any separation), and
  // GCC-PHAT on it misplaces the drone by tenths of a degree with no noise at all. A far
  // source's mic moduli are equal, so b = P b + a c for the c that equalises |(P b + a c)_m|;
  // solved by Gauss-Newton on (Re c, Im c) from c = 0 (docs/doa.md stage 3c, session 24).
  bool refill_plane_wave = true;
};

class StaticSourceCancel {
 public:
  // `gcc` fixes the mics and the band.
  StaticSourceCancel(const GccPhat& gcc, StaticCancelSettings settings);

  // After StaticSourceNull::mask(), before any correlation: every band bin the mask dropped
  // teaches its owner's covariance; once learned it is projected orthogonal to the owner's
  // steering vector (gcc's units and levels of that bin rewritten), kept again, and every pair's
  // cross-power of that bin remade. Bins the mask kept are untouched.
  void apply(GccPhat& gcc);

  // Share of the band bins cancelled (kept after projection) in the last apply().
  double cancelled_share() const { return cancelled_share_; }
  // The learned unit steering vector of one band bin (mic order), for tests.
  std::complex<double> steering(int band_index, int mic) const {
    return steering_[static_cast<std::size_t>(band_index * mics_ + mic)];
  }

 private:
  // Mic counts up to this get the eigenvalue split (fixed-size storage, no allocation per frame);
  // larger arrays fall back to everything the owner leaves as the noise's share.
  static constexpr int kMaxEigenMics = 8;
  // The noise's share of a bin is solved again every this many frames the bin is owned (0.5 s
  // at 50 ms hops, a sixth of the covariance's 3 s average): one eigenvalue solve a frame for
  // every bin cost ~1 us per bin (doa_bench /12: 244 -> 513 us CPU a frame).
  static constexpr int kNoiseRefreshFrames = 10;
  using Covariance = Eigen::Matrix<std::complex<double>, Eigen::Dynamic, Eigen::Dynamic, 0,
                                   kMaxEigenMics, kMaxEigenMics>;
  // The share of a bin the noise leaves after the projection, from its learned covariance.
  double noise_residual_share(const std::complex<double>* covariance,
                              const std::complex<double>* steering);
  // spectrum_ (P x, power residual2) += a c, c the component that equalises the mics' moduli;
  // kept as P x when the refilled bin would hold more than bin_power, |x|^2 before the cancel.
  void refill_plane_wave(const std::complex<double>* steering, double residual2, double bin_power);

  StaticCancelSettings settings_;
  int mics_ = 0;
  int bins_ = 0;
  // Per band bin: the mics' covariance (row-major mics x mics), the unit steering vector, and
  // how many frames taught it.
  std::vector<std::complex<double>> covariance_;
  std::vector<std::complex<double>> steering_;
  std::vector<int> updates_;
  std::vector<std::complex<double>> spectrum_;  // one bin's mic vector
  std::vector<std::complex<double>> iterated_;  // R a
  std::vector<std::uint8_t> cancelled_bins_;    // per band bin: 1 = projected this frame
  std::vector<double> noise_share_;             // per band bin: noise_residual_share(), -1 unset
  double cancelled_share_ = 0.0;
  Covariance eigen_input_;
  Eigen::SelfAdjointEigenSolver<Covariance> eigen_;
};

}  // namespace dronetrack::doa
