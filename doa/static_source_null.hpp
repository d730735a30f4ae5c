#pragma once
// Static-source null: finds sound sources that stay put at or below the horizon (a generator,
// a pump, a road junction) from the per-frame GCC peaks, and then drops, frame by frame, the
// band bins whose PHAT cross-spectra match such a source's TDOAs on all pairs, before the
// inverse FFTs. A drone's rotor harmonics occupy other bins (W-disjoint orthogonality: in a
// time-frequency bin one source dominates), so its correlation peak survives the null even when
// the static source is louder in the band as a whole.
//
// Learning is in TDOA space, not direction space: a source 5 m away is in the near field of a
// 0.8 m array (its TDOAs do not fit a plane wave), but its TDOAs are just as constant. The
// direction is only used for the gate that keeps the sky free: a static source is nulled only
// when its (plane-wave) elevation is at most `max_elevation_deg`, so a hovering drone is never
// nulled. Planar arrays see up and down alike: the upper mirror image must pass the gate; line
// arrays cannot tell and null nothing.
//
// Per frame: mask() between GccPhat::whiten() and GccPhat::correlate(), observe() after
// correlate(). Everything is sized in the constructor; nothing is allocated per frame.
#include <array>
#include <complex>
#include <span>
#include <vector>

#include "doa/array_geometry.hpp"
#include "doa/doa_params.hpp"
#include "doa/gcc_phat.hpp"

namespace dronetrack::doa {

struct StaticNullSettings {
  double hop_s = 0.05;             // time between frames (observe() counts frames)
  double learn_s = 3.0;            // a source must stay put this long before it is nulled
  double forget_s = 2.0;           // a nulled source not heard for this long is forgotten
  double max_elevation_deg = 3.0;  // only sources at or below this elevation are nulled
  double tolerance_s = 20e-6;      // per pair: a frame's TDOA this close matches a source
  int max_sources = 2;             // static sources nulled at once
  // A band bin is dropped when the mean over pairs of cos(phase - w tau_source) reaches this:
  // one dominant source gives ~1, noise or another source's bin ~0 +- 0.3 (4 mics).
  double match_threshold = 0.5;
  double speed_of_sound_mps = 343.0;
  // Follow each bin's steady phase (the source's ground reflection bends it) instead of the
  // pure delay model alone.
  bool adapt_bins = true;
};

// The settings the "doa" config keys give (static_null_*).
StaticNullSettings static_null_settings(const DoaParams& params, double hop_s,
                                        double speed_of_sound_mps);

class StaticSourceNull {
 public:
  // `gcc` fixes the pairs and the band; geometry gives the pairs' mic positions.
  StaticSourceNull(const ArrayGeometry& geometry, const GccPhat& gcc, StaticNullSettings settings);

  // Between gcc.whiten() and gcc.correlate(): clears the bins of every nulled source in
  // gcc.bin_keep() and notes whether each is still heard.
  void mask(double time_s, GccPhat& gcc);
  // After gcc.correlate(): learns static sources from the frame's per-pair peaks. `usable`:
  // a clean frame with sharp correlations (the pipeline's own test).
  void observe(double time_s, const GccPhat& gcc, bool usable);

  int nulled_count() const;
  // TDOAs (s, per pair) of the nulled sources, in slot order; for tests and diagnostics.
  int nulled_tdoas(int nulled_index, std::span<double> tdoas_s) const;
  // Share of the band bins dropped in the last mask().
  double dropped_share() const { return dropped_share_; }

 private:
  static constexpr int kSlots = 6;  // tentative + nulled + sky sources followed at once
  static constexpr int kMaxPairs = 28;
  static constexpr int kMaxMics = 8;
  enum class State { empty, tentative, nulled, sky };
  struct Slot {
    State state = State::empty;
    std::array<double, kMaxPairs> tdoa_s{};
    double first_s = 0.0;
    double last_heard_s = 0.0;
    int hits = 0;
    int frames = 0;
    int signature = -1;  // index into signatures_ when nulled
  };

  bool matches(const Slot& slot, std::span<const double> tdoas_s) const;
  bool heard(const GccPhat& gcc, const Slot& slot);
  // The TDOAs close around every mic triple (one source, not peaks of two mixed across pairs).
  // Needs every pair of the triples; pairs the GccPhat does not have are skipped.
  bool consistent(std::span<const double> tdoas_s) const;
  void decide(Slot& slot);
  void make_signature(Slot& slot);
  void adapt(int signature_index, const GccPhat& gcc);
  // Elevation (deg) of the highest direction consistent with the TDOAs (plane wave; planar
  // arrays: the upper mirror image). +90 when the geometry cannot tell (line arrays).
  double highest_elevation_deg(std::span<const double> tdoas_s) const;

  StaticNullSettings settings_;
  int pair_count_ = 0;
  int band_bins_ = 0;
  std::vector<BandRun> band_;
  double bin_omega_ = 0.0;  // rad/s per FFT bin
  int geometry_rank_ = 0;
  int mic_count_ = 0;
  std::array<int, kMaxMics * kMaxMics> pair_index_{};  // [i * 8 + j] -> pair (i, j), or -1
  std::vector<Eigen::Vector3d> pair_baselines_m_;      // p_i - p_j, array frame (z is site z)
  Eigen::Matrix3d normal_inverse_ = Eigen::Matrix3d::Zero();  // pseudo-inverse of D^T D
  Eigen::Vector3d plane_normal_ = Eigen::Vector3d::UnitZ();   // planar arrays
  std::array<Slot, kSlots> slots_{};
  // Per nulled source: e^{j w_k tau_p} (or the bin's steady phase), pair-major over the band.
  std::vector<std::vector<std::complex<double>>> signatures_;
  std::vector<std::vector<std::complex<double>>> averages_;  // per-bin mean of conj(W)
  std::vector<std::vector<std::complex<double>>> models_;    // the pure delay model
  std::vector<bool> signature_used_;
  std::vector<double> scores_;        // per band bin: match with one source's signature
  std::vector<double> model_scores_;  // per band bin: match with its pure delay model
  std::vector<double> bin_power_;     // per band bin: sum over pairs of |G|
  std::vector<double> frame_tdoas_;   // per pair
  std::vector<double> slot_tdoas_;    // per pair: a slot's refined peaks in this frame
  double dropped_share_ = 0.0;
};

}  // namespace dronetrack::doa
