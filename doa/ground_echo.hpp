#pragma once
// The ground's reflection of one source, measured and divided out of the mics' phases.
//
// An array stands a metre or two above flat ground, so every mic hears a drone twice: directly
// and from its mirror image under the ground, g (0..1) times as loud and later by
// Delta_i = (|r' - m_i| - |r - m_i|) / c (r' = r mirrored in the ground plane). Each mic's
// spectrum is X_i = S e^{-j w t_i} (1 + g_i e^{-j w Delta_i}): a comb that differs from mic to mic
// (their heights differ), so PHAT's phases carry arg(1 + g_i e^{-j w Delta_i}) on top of the
// direct path. A rotor's harmonics sample that comb at a few frequencies only, so the error does
// not average out over the band: it pulls the TDOAs, and with them mostly the elevation, by a few
// tenths of a degree, for seconds at a time (seed-002 scene: A1's elevation +0.1..+0.25 deg).
//
// Given the direct path's direction, the mics' echo delays follow from the source's range and the
// ground's height alone, and the comb's depth from g. The pair (range, g) is searched: the one
// whose combs, divided out of every mic's phase, leave the frame's phasors most coherent along the
// direct path. It is kept (locked) only while it explains the frames clearly better than no echo.
// Range and g change slowly, so once locked a small local search every few frames follows them;
// the mics' delays are recomputed every frame from the frame's own direction.
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/array_geometry.hpp"
#include "doa/gcc_phat.hpp"

namespace dronetrack::doa {

struct GroundEchoSettings {
  double ground_height_m = 0.0;         // site z of the reflecting ground under the array
  double min_range_m = 4.0;             // nearest source searched
  double min_elevation_deg = 2.0;       // lower, the echo is the direct path itself
  double min_improvement = 0.02;        // relative coherence gain that counts as an echo
  int search_every_frames = 4;          // local search period while locked
  int acquire_every_frames = 20;        // full search period while not locked
  double max_direction_jump_deg = 3.0;  // a larger jump is another source: search again
};

class GroundEcho {
 public:
  GroundEcho(const ArrayGeometry& geometry, const GccPhat& gcc, double speed_of_sound_mps,
             GroundEchoSettings settings = {});

  // Follows the echo of a source whose direct path comes from `direction_site` (unit, from the
  // array centre) on this frame's per-mic units (kept bins, bin weights). Returns whether an echo
  // is locked; remove() then divides it out.
  bool observe(const GccPhat& gcc, const Eigen::Vector3d& direction_site);
  // The same on the band bins `keep` marks (band order) instead of gcc.bin_keep(): the
  // source's own bins without remaking the pairs' phasors for them.
  bool observe(const GccPhat& gcc, const Eigen::Vector3d& direction_site,
               std::span<const std::uint8_t> keep);
  // Whether the next observe() searches (reads the units, the kept bins and their weights);
  // otherwise it only follows the direction.
  bool search_due(const Eigen::Vector3d& direction_site) const;
  // The mics' units with the locked echo, for the source's direction now, divided out: a view
  // of this object's rows (valid until its next corrected()), or `units` itself when no echo is
  // locked. `units` stay as they are.
  GccPhat::UnitsView corrected(const GccPhat::UnitsView& units,
                               const Eigen::Vector3d& direction_site);
  // Cosine between `direction_site` and the direction last observed: which source this follows.
  double alignment(const Eigen::Vector3d& direction_site) const {
    return direction_site.dot(last_direction_);
  }
  void reset();

  bool locked() const { return locked_; }
  double range_m() const;  // infinity for plane waves
  double gain() const { return gain_; }

 private:
  // Per mic, for a source at curvature 1/range: the direct path's arrival time (a plane wave:
  // coherence is judged against the same direct path for every candidate, so that a candidate's
  // curvature cannot buy coherence by bending the direct path), the echo's delay and relative
  // level.
  void paths(const Eigen::Vector3d& direction_site, double curvature_per_m);
  // The search's bins for this frame (the strongest weights, at most kSearchBins spread over
  // the band), their units aligned on the direct path from `direction_site`.
  void prepare(const GccPhat& gcc, std::span<const std::uint8_t> keep,
               const Eigen::Vector3d& direction_site);
  // paths() for a search candidate, and its echoes at the search bins.
  void candidate(const Eigen::Vector3d& direction_site, double curvature_per_m);
  // Weighted mean coherence of the prepared bins with the candidate's combs removed (gain 0:
  // as they are), in [0, 1].
  double coherence(double gain) const;
  void search(const GccPhat& gcc, std::span<const std::uint8_t> keep,
              const Eigen::Vector3d& direction_site, bool full);
  // What observe() will do for this direction: the one place the search schedule is decided.
  enum class Search { none, local, full };
  Search next_search(const Eigen::Vector3d& direction_site) const;

  GroundEchoSettings settings_;
  double speed_of_sound_mps_;
  std::vector<Eigen::Vector3d> mics_m_;  // relative to the centre
  std::vector<double> mic_heights_m_;    // above the ground
  double centre_height_m_ = 0.0;
  std::vector<BandRun> runs_;
  double bin_omega_ = 0.0;
  std::vector<double> band_omega_;  // rad/s per band bin
  double min_sine_elevation_ = 0.0;
  double max_jump_cosine_ = 1.0;
  // Per mic, for the current candidate.
  std::vector<double> arrival_s_;
  std::vector<double> delay_s_;
  std::vector<double> level_;
  // prepare(): per search bin, its angular frequency and weight, and per mic and bin (mic-major,
  // kSearchBins per mic, zero after search_bins_) the unit aligned on the direct path;
  // candidate(): per mic and bin the echo relative to the direct path, level e^{-j w Delta}.
  int search_bins_ = 0;
  double search_weight_sum_ = 0.0;
  std::vector<double> search_omega_;
  std::vector<double> search_weight_;
  std::vector<double> aligned_re_;
  std::vector<double> aligned_im_;
  std::vector<double> echo_re_;
  std::vector<double> echo_im_;
  std::vector<int> candidates_;       // scratch: band indices with a large enough weight
  std::vector<double> corrected_re_;  // corrected(): per mic over the band bins
  std::vector<double> corrected_im_;

  bool locked_ = false;
  double curvature_per_m_ = 0.0;
  double gain_ = 0.0;
  Eigen::Vector3d last_direction_ = Eigen::Vector3d::Zero();
  int frames_since_search_ = 0;
};

}  // namespace dronetrack::doa
