#pragma once
// Static-source look (issue 14: a hovering drone under louder sources). A static source's pair
// cross-phasors keep their phase from frame to frame; a moving source's turn with its direction
// and noise's are random. Averaged over frames (per pair and bin, W_avg = a W_avg + (1 - a) W,
// a = exp(-hop / averaging_time_s)) and normalised to unit length, the static source gains on
// both, so one more SRP look on the average (after the frame's own, with their sources' bins
// dropped) finds a source the frame's own looks miss under louder ones. Its peak is then
// measured on the frame's own phasors (the node's regular re-measure): the average only says
// where to look, never what the frame measured.
//
// A look's direction counts only when it is static: within max_drift_deg of one of this
// object's looks hold_s to 2 hold_s earlier (a moving source's average is smeared and its peak
// wanders: a drone 200 m out at 10 m/s crosses ~3 deg/s), and min_elevation_deg or more above
// the horizon (a generator and its ground image merge near 0 deg; the static null's business).
//
// Per frame: accumulate() right after GccPhat::whiten() (the unmasked, unweighted phasors),
// load_average() for the look, held() on the look's direction. Everything is sized in the
// constructor; nothing is allocated per frame.
#include <complex>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/doa_params.hpp"
#include "doa/gcc_phat.hpp"

namespace dronetrack::doa {

class StaticSourceLook {
 public:
  // `gcc` fixes the pairs and the band; hop_s is the time between frames.
  // max_sources: the own looks' sources a frame, at most.
  StaticSourceLook(const GccPhat& gcc, double hop_s, int max_sources,
                   const StaticLookSettings& settings);

  // After gcc.whiten(): this frame's phasors into the average.
  void accumulate(const GccPhat& gcc);
  // The averaged phasors (unit length) into gcc under `keep`, unweighted; correlate next.
  void load_average(GccPhat& gcc, std::span<const std::uint8_t> keep) const;
  // The frame's own looks' sources (site frame), every frame before the look: a look within
  // `separation_cosine` of one found within own_look_memory_s is theirs (explained()).
  void note_found(double time_s, std::span<const Eigen::Vector3d> directions_site);
  bool explained(double time_s, const Eigen::Vector3d& direction_site,
                 double separation_cosine) const;
  // Records this look's direction (site frame, unit) at time_s; true when it is static (within
  // max_drift_deg of a look hold_s..2 hold_s earlier) and high enough.
  bool held(double time_s, const Eigen::Vector3d& direction_site);

 private:
  struct Look {
    double time_s = -1e300;
    Eigen::Vector3d direction = Eigen::Vector3d::Zero();
  };
  StaticLookSettings settings_;
  double keep_share_;  // a, per frame
  double drift_cosine_;
  double min_elevation_sine_;
  std::vector<std::complex<double>> average_;  // per pair, band bins, as GccPhat::phasors()
  std::vector<Look> looks_;                    // ring over 2 hold_s of frames
  std::size_t next_look_ = 0;
  std::vector<Look> found_;  // ring: the own looks' sources over own_look_memory_s
  std::size_t next_found_ = 0;
};

}  // namespace dronetrack::doa
