#pragma once
// Acoustic evidence per source at the node (issue 14): what a source's own spectrum says about
// what it is. Each frame's sources are steered to (delay-and-sum on the FFTs the node already
// made) and every band bin goes to the source whose steering makes it most coherent across the
// mics, if coherent enough: a drone's harmonic comb and a car's broadband land in different
// bins (W-disjoint orthogonality, as in SourceBinMask). On each source's own bins a
// HarmonicCombDetector looks for a rotor's comb; a history per source (the node's source-track
// slot) gives the features over the last seconds. The fusion's classifier reads them
// (fusion/track_classifier.hpp). Preallocated; nothing is allocated per frame.
#include <array>
#include <complex>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/array_geometry.hpp"
#include "doa/doa_measurement.hpp"
#include "doa/doa_params.hpp"
#include "doa/gcc_phat.hpp"
#include "doa/harmonic_comb.hpp"
#include "doa/spectral_frame.hpp"

namespace dronetrack::doa {

class AcousticFeatureExtractor {
 public:
  static constexpr int kMaxSlots = 16;
  static constexpr int kMaxSources = 8;

  // Throws std::invalid_argument naming a bad setting.
  AcousticFeatureExtractor(const ArrayGeometry& geometry, int fft_size, double sample_rate_hz,
                           double speed_of_sound_mps, double hop_s,
                           const AcousticSettings& settings);

  // Whether this frame is one the features are measured on (every analysis_every_frames).
  bool due(std::int64_t frame_index) const {
    return settings_.enabled && frame_index % settings_.analysis_every_frames == 0;
  }
  // This frame's sources: site-frame directions (strongest first), each source's slot (the
  // node's source track, 0..kMaxSlots-1) and that slot's generation (a new source in an old
  // slot starts a new history).
  void analyse(const MultichannelFft& fft, std::span<const Eigen::Vector3d> directions_site,
               std::span<const int> slots, std::span<const std::uint32_t> generations);
  // The slot's latest features (valid = false before its first analysis).
  const AcousticFeatures& features(int slot) const;

 private:
  struct History {
    std::uint32_t generation = 0;
    bool started = false;
    std::vector<double> mean_autocorrelation;
    struct Entry {
      bool comb = false;
      double fundamental_hz = 0.0;
      double level_db = 0.0;
    };
    std::vector<Entry> entries;  // ring
    int next = 0;
    int size = 0;
    AcousticFeatures features;
  };
  void assign_bins(const MultichannelFft& fft, int sources);
  // Whether the harmonics of `comb` point at `source`: their steered power over the bands'
  // broadband peaks within line_direction_tolerance_deg of its direction (rings out to 20 deg).
  // Leaves the harmonics' bins in line_bins_.
  bool lines_point_at(const MultichannelFft& fft, const HarmonicComb& comb, int source);
  // The harmonics of `fundamental_hz` into line_bins_ (on_line_) and their line_excess().
  void make_lines(const MultichannelFft& fft, double fundamental_hz);
  // line_bins_' cross-spectral matrices less their off-line neighbours' mean, into line_excess_.
  void line_excess(const MultichannelFft& fft);
  double line_power(const Eigen::Vector3d& direction) const;
  // line_bins_ set to the source's background in its spectrum `power`.
  void drop_lines(std::span<double> power);
  void update_history(History& history, const HarmonicComb& comb, double level_db);

  AcousticSettings settings_;
  double interval_s_;   // between analyses
  double comb_weight_;  // of a new autocorrelation in the mean (analysis interval / memory)
  int mic_count_;
  BandRun band_;  // the feature band's bins
  int first_bin_;
  int bin_count_;
  double bin_omega_;                                 // rad/s per bin
  std::vector<Eigen::Vector3d> mic_offsets_site_m_;  // from the mic centroid, site frame
  double speed_of_sound_mps_;
  HarmonicCombDetector detector_;
  static constexpr int kMaxMics = 8;
  std::array<std::array<double, kMaxMics>, kMaxSources> delays_s_{};  // per source, per mic
  std::vector<double> source_power_;                                  // kMaxSources x bin_count_
  std::vector<double> mic_power_;                  // per bin: mean power over the mics
  std::vector<double> sorted_power_;               // for the median
  std::array<double, kMaxSources> owned_power_{};  // per source: its own bins' power
  std::vector<double> frame_autocorrelation_;
  std::vector<double> mean_before_;  // a slot's mean autocorrelation before this analysis
  std::array<Eigen::Vector3d, kMaxSources> source_directions_{};  // this analysis's, site frame
  std::vector<std::uint8_t> on_line_;  // per feature-band bin: on the comb being checked
  std::vector<int> line_bins_;         // those bins (FFT bin minus first_bin_)
  double lines_fundamental_hz_ = 0.0;  // the spacing line_bins_ were made for this frame (0: none)
  std::vector<std::complex<double>> line_excess_;  // per line bin: M x M, upper triangle
  double typical_power_ = 0.0;                     // the frame's median mic power over the band
  double line_tolerance_rad_ = 0.0;                // line_direction_tolerance_deg
  std::array<History, kMaxSlots> histories_;
  AcousticFeatures none_;
};

}  // namespace dronetrack::doa
