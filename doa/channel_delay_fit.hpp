#pragma once
// The channel-skew check's estimator (issue 16): one extra delay per channel of a 3-D array,
// fitted online from the misfit of each source frame's pair delays to a plane wave, with the
// slowness's scale (the speed of sound the node assumes) a free nuisance, and a standard
// deviation that holds the direction-dependent biases of the pair delays (echo, near field).
//
// Why a covariance and not a threshold: per frame the pair delays give one scalar about the
// delays, the radial error of the fitted slowness (a tetrahedron's pair delays are exactly those
// of some slowness vector: a delay on channel c shifts the slowness by v = F d, and only the
// length |u/c + v| - 1/c ~ u . v shows). A delay is therefore seen only through how that error
// changes over the source directions u, and one source passing over a narrow set of directions
// cannot tell a channel's delay from an error of the slowness's length or from a bias that
// follows the direction. The frames are grouped by direction sector; the fit is the sum over
// sectors, and its covariance is the cluster-robust ("sandwich") one over sectors: frames of one
// sector share their biases, so a sector counts as one independent look, not as its frames.
// A delay is judged only when enough sectors were seen, and said when it is several of those
// standard deviations from zero and over a physical minimum.
//
// Plain logic on Eigen: no I/O, no clock; everything sized in the constructor, observe() and
// solve() allocate nothing.
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/direction_sectors.hpp"
#include "doa/doa_measurement.hpp"

namespace dronetrack::doa {

inline constexpr int kMaxFitChannels = 8;

class ChannelDelayFit {
 public:
  using PairVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxPairs, 1>;
  using PairBySpace = Eigen::Matrix<double, Eigen::Dynamic, 3, 0, kMaxPairs, 3>;
  using PairByChannel =
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxPairs, kMaxFitChannels>;
  // Channel delays and then the slowness-scale nuisance.
  using ParameterVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxFitChannels + 1, 1>;
  using ParameterMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0,
                                        kMaxFitChannels + 1, kMaxFitChannels + 1>;

  struct Settings {
    double window_s = 30.0;          // frames are forgotten with this time constant
    double prior_us = 1000.0;        // each channel delay's prior std (keeps unseen ones at 0)
    double scale_prior = 0.05;       // the slowness scale's prior std (5 %: 30 K of air)
    int sectors = 32;                // direction sectors over the sphere
    double min_sector_frames = 5.0;  // a sector counts as seen with this many frames
  };

  // One channel's estimate at the last solve().
  struct ChannelDelay {
    double offset_us = 0.0;  // its delay minus the median channel's
    double std_us = 0.0;     // that offset's cluster-robust std
  };

  // `pair_vectors_m`: row (i, j) = p_j - p_i, pairs i < j lexicographic; the array must span
  // three dimensions (the caller checks). `hop_s`: the time between frames.
  ChannelDelayFit(const PairBySpace& pair_vectors_m, int channels, double speed_of_sound_mps,
                  double hop_s, const Settings& settings);

  // One source frame's pair delays (tau_ij = t_i - t_j). Returns false, and takes nothing, when
  // they are not one plane wave (the slowness's length off 1/c by more than half).
  bool observe(const PairVector& tdoas_s);
  // Solves with what has been seen so far; channel_delays() then holds the estimates.
  void solve();

  std::span<const ChannelDelay> channel_delays() const {
    return {delays_.data(), static_cast<std::size_t>(channels_)};
  }
  // Forgetting-weighted count of the frames taken, and the sectors that hold at least
  // min_sector_frames of them (at the last solve()).
  double frames() const { return frames_; }
  int sectors_seen() const { return sectors_seen_; }
  // The slowness's fitted scale error (dimensionless; +0.01: the delays say sound is 1 % slower).
  double scale_error() const;
  // The free parameters: channels - 1 delays (their mean is the clock's) and the scale.
  int free_parameters() const { return channels_; }

 private:
  struct Sector {
    ParameterMatrix information;  // sum of J^T J
    ParameterVector score;        // sum of J^T (r + J x_linearised)
    double frames = 0.0;
    long long updated_frame = 0;  // the frame index its sums were last decayed to
  };
  void decay(Sector& sector) const;

  int channels_;
  int parameters_;
  double speed_of_sound_mps_;
  Settings settings_;
  double forgetting_;
  double scale_length_s_;  // the scale parameter's unit: the array's rms radius over c
  DirectionSectors sector_of_;
  PairBySpace geometry_{};
  Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxPairs> geometry_inverse_{};
  PairByChannel out_of_range_{};  // E = (I - G G^+) D
  Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxFitChannels> slowness_of_delays_{};  // G^+ D
  PairByChannel difference_{};                                                            // D
  std::vector<Sector> sectors_{};
  long long frame_index_ = 0;
  double frames_ = 0.0;
  double square_sum_ = 0.0;  // forgetting-weighted sum of the misfits' squares (s^2)
  int sectors_seen_ = 0;
  ParameterVector estimate_{};  // delays (s) and scale (in scale_length_s_)
  std::vector<ChannelDelay> delays_{};
  // Scratch, sized once.
  PairVector tdoas_{};
  PairVector misfit_{};
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxPairs, kMaxFitChannels + 1>
      jacobian_{};
  ParameterMatrix system_{};
  ParameterMatrix meat_{};
  ParameterVector vector_{};
  ParameterVector sector_score_{};
};

}  // namespace dronetrack::doa
