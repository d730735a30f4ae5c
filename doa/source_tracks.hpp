#pragma once
// Several sources over time on one time base. Each frame's sources (every pair's per-frame TDOA
// of one source, with the direction they solve to) are associated with persistent source tracks
// by direction, and each track smooths its own TDOAs with the robust regression (seed 002).
// Every estimate out of one update() refers to the same earlier frame, output_delay_s() back,
// whichever source it belongs to: the strongest source and the second drone are never mixed
// between "now" and "0.3 s ago", and no source is reported twice for one frame.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/doa_measurement.hpp"
#include "doa/ls_doa_solver.hpp"
#include "doa/tdoa_tracker.hpp"

namespace dronetrack::doa {

struct SourceObservation {
  Eigen::Vector3d direction_site = Eigen::Vector3d::UnitX();
  std::span<const PairTdoa> tdoas;  // one per pair, this frame (variance <= 0: pair absent)
};

struct SourceEstimate {
  std::array<PairTdoa, kMaxPairs> tdoas{};  // smoothed, for time_s - output_delay_s()
  double strength = 0.0;                    // mean GCC peak value over the window's points
  int track = -1;                           // the track's slot, stable while it lives
};

class SourceTracks {
 public:
  // association_gate_deg: how far an observation may lie from its track's last direction, plus
  // the settings' max_angular_rate_dps times the time since that direction.
  SourceTracks(int pair_count, int max_tracks, const TdoaTrackerSettings& settings,
               double association_gate_deg);

  // One frame. `observations` strongest first. Fills `out` with the estimates of every track
  // that had a point output_delay_s() ago, strongest first; returns how many.
  int update(double time_s, std::span<const SourceObservation> observations,
             std::span<SourceEstimate> out);
  double output_delay_s() const { return delay_s_; }
  int live_tracks() const;
  int slot_count() const { return static_cast<int>(tracks_.size()); }
  // After update(): the index of this frame's observation the slot took (-1: none), and how many
  // tracks the slot has started (a new source in an old slot has a new generation).
  int observation_of(int slot) const { return tracks_[static_cast<std::size_t>(slot)].observation; }
  std::uint32_t generation(int slot) const {
    return tracks_[static_cast<std::size_t>(slot)].generation;
  }
  // Before update(): whether the slot holds a track, its last direction, and how far from it
  // an observation at time_s may lie and still be its (the association gate, degrees).
  bool live(int slot) const { return tracks_[static_cast<std::size_t>(slot)].live; }
  const Eigen::Vector3d& direction_site(int slot) const {
    return tracks_[static_cast<std::size_t>(slot)].direction_site;
  }
  double gate_deg(int slot, double time_s) const;
  // Whether the slot's track may be measured from its own lags at time_s (a followed source,
  // doa.follow_source_tracks): only from an observation one hop old. A source moves a fraction
  // of a degree in a hop, well inside the fringe it was on; the gate widens by
  // max_angular_rate_dps every hop unheard (2 + 90 x 0.1 = 11 deg after two), as far as a
  // lines-only source's neighbouring carrier fringe (~11 deg in elevation on a 0.67 m tetrahedron
  // at 2.7 kHz), so a follow after a gap can land on the wrong fringe, and a source that faded or
  // was hidden by a louder one is looked for afresh by the free search instead.
  bool followable(int slot, double time_s) const;

 private:
  struct Track {
    explicit Track(int pair_count, const TdoaTrackerSettings& settings)
        : regression(pair_count, settings) {}
    TdoaRegression regression;
    Eigen::Vector3d direction_site = Eigen::Vector3d::UnitX();
    double last_time_s = 0.0;
    bool live = false;
    int observation = -1;  // this frame's observation, -1 if none
    std::uint32_t generation = 0;
  };

  int pair_count_;
  double delay_s_;
  double max_age_s_;
  double max_angular_rate_dps_;
  double hop_s_;
  double association_gate_deg_;
  std::vector<Track> tracks_;
  std::vector<char> observation_taken_;
};

}  // namespace dronetrack::doa
