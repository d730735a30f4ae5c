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
// A search over every direction on the average costs a correlation and an SRP look (more than
// the rest of the look together), and a hovering drone's direction does not change from frame
// to frame: the search runs every search_every_frames frames, and a source it added is held
// (hold()) and measured again every frame near its held direction alone (follow()), until a
// frame's measurement is no longer the same source or the own looks take it over. A
// search lands first on what leads the average: up to max_looks looks a frame, each after the
// last one's lobe is taken out, so a louder neighbour (explained, or not static) does not hide it.
//
// The test that a direction is static is made in the array's frame: an array that moves
// (a pose track) must reset() it, or a source riding with the platform would count as static.
//
// Per frame: accumulate() right after GccPhat::whiten() (the unmasked, unweighted phasors),
// then follow() the held source or, when search_due(), load_average() for the search and held()
// on each look's direction. Everything is sized in the constructor; nothing is allocated per
// frame.
#include <complex>
#include <cstdint>
#include <limits>
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
  // The same with the found sources' bins dropped and the phasors weighted as they are made
  // (GccPhat::cross_power_from() with owners): correlate next.
  void load_average(GccPhat& gcc, std::span<const std::uint8_t> keep,
                    const BinOwners& owners) const;
  // The frame's own looks' sources (site frame), every frame before the look: a look within
  // `separation_cosine` of one found within own_look_memory_s is theirs (explained()).
  void note_found(double time_s, std::span<const Eigen::Vector3d> directions_site);
  bool explained(double time_s, const Eigen::Vector3d& direction_site,
                 double separation_cosine) const;
  // Records this look's direction (site frame, unit) at time_s; true when it is static (within
  // max_drift_deg of a look hold_s..2 hold_s earlier) and high enough.
  bool held(double time_s, const Eigen::Vector3d& direction_site);

  // The source a search added, to be measured again every frame near held_direction().
  void hold(const Eigen::Vector3d& direction_site);
  bool holding() const { return holding_; }
  const Eigen::Vector3d& held_direction() const { return held_direction_; }
  // A frame's measurement of the held source: true (and the held direction recorded as a look
  // at time_s, so held() still sees it) when it is within `separation_cosine` of the held
  // direction (the node's same-source test) and high enough; false lets it go (lose()).
  bool follow(double time_s, const Eigen::Vector3d& direction_site, double separation_cosine);
  void lose();
  // Whether this frame (counted by accumulate()) searches every direction: every
  // search_every_frames frames, and every frame for that many after the held source was lost.
  bool search_due() const;
  // Forgets every look's direction and the held source (the array moved: directions seen
  // before are not comparable). The average and the own looks' sources stay.
  void reset();

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
  bool holding_ = false;
  Eigen::Vector3d held_direction_ = Eigen::Vector3d::UnitZ();
  std::int64_t frame_ = 0;  // accumulate() calls
  std::int64_t lost_frame_ = std::numeric_limits<std::int64_t>::min() / 2;
};

}  // namespace dronetrack::doa
