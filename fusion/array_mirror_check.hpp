#pragma once
// Names two swapped channels of an array that no check at its node can see (issue 16). On an
// array where the plane bisecting mics a and b holds every other mic (each edge of a regular
// tetrahedron), swapping the two channels is exactly a reflection of the array through that plane:
// the node hears the mirror world and reports, for a source in direction u (array frame), the
// direction S u with S = I - 2 n n^T, n the unit vector from b to a. Closure, the plane-wave fit
// and every level agree with it; only a direction known from elsewhere can tell. The fusion has
// one: a track fixed by OTHER arrays. Each of the array's DOAs is compared with the directions
// from the array to such tracks as wired and under each mirror S_ab.
//
// The evidence is grouped like the node's delay fit: per direction sector of the source (seen
// from the array), the mean angular misfit as wired and under each mirror, over the DOAs where
// that mirror moves the direction by at least min_separation_deg (near its plane a mirror and the
// wiring are the same prediction and tell nothing); a sector counts as one look however long the
// source stays in it. A swap is named when, over at least min_sectors sectors, the wiring's mean
// misfit is at least evidence_ratio times the mirror's (floored at floor_deg), on two judgements
// in a row that name the same swap.
//
// Why a rotation (a yaw set a few degrees off) is never read as a swap: a DOA counts only where
// some hypothesis explains it within gate_deg, and for the mirror only where the mirror moves the
// direction by min_separation_deg or more. A rotation by theta moves every direction by at most
// theta, so where the mirror separates (by s >= min_separation_deg) the rotated DOA is at least
// s - theta from the mirror's prediction: below min_separation_deg - gate_deg (15 deg at the
// defaults) no rotation brings a DOA within the gate of a mirror where the mirror counts, and the
// wiring's misfit (theta) stays the smaller.
//
// Plain logic on Eigen: no I/O, no clock; sized in the constructor, observe() allocates nothing.
#include <array>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/array_geometry.hpp"
#include "doa/direction_sectors.hpp"

namespace dronetrack::fusion {

// Keys under fusion.mirror_check (docs/calibration.md "Swaps the node cannot see").
struct MirrorCheckSettings {
  bool enabled = true;
  double gate_deg = 5.0;  // a DOA is evidence when a hypothesis puts it this near a track
  double min_separation_deg = 20.0;  // a mirror counts where it moves the direction this much
  double evidence_ratio = 5.0;       // wiring's mean misfit / the mirror's, at least this
  double floor_deg = 0.5;            // the mirror's misfit is taken as at least this in the ratio
  int min_sectors = 4;               // direction sectors judged before a swap is named
  double min_sector_doas = 5.0;      // DOAs (forgetting-weighted) for a sector to be judged
  int sectors = 32;                  // the sphere's direction sectors (doa/direction_sectors.hpp)
  double window_s = 120.0;           // the evidence is forgotten with this time constant
  int judge_doas = 20;               // judged every this many evidence DOAs
  // Other mics this far from a pair's bisector plane, as a share of the pair's spacing, still
  // make the swap a mirror (1 %: ~0.6 deg of DOA at most).
  double symmetry_tolerance = 0.01;
  // Which tracks are references (the engine's part): heard within the last second by at least
  // min_other_arrays arrays besides the one judged, position known to max_track_angle_deg seen
  // from that array (1 sigma, across its ray).
  int min_other_arrays = 2;
  double max_track_angle_deg = 2.0;
  double rewarn_s = 60.0;  // a swap named is not named again sooner than this
};

// A swap named.
struct MirrorSwapEvent {
  int array = 0;      // index in the site
  int channel_a = 0;  // the two channels (mic indices, a < b)
  int channel_b = 0;
  double time_s = 0.0;              // of the judgement
  double wired_misfit_deg = 0.0;    // mean over the judged sectors, as wired
  double swapped_misfit_deg = 0.0;  // and under the mirror
  double evidence_ratio = 0.0;      // wired / max(swapped, floor_deg)
  int sectors = 0;                  // judged
};

// The check's standing on one array (the fusion's diagnostics).
struct MirrorCheckStatus {
  int array = 0;
  int mirrors = 0;             // swaps of this array that are mirrors (tested)
  double evidence_doas = 0.0;  // DOAs taken so far (not forgotten)
  int best_channel_a = -1;     // the mirror with the largest ratio at the last judgement
  int best_channel_b = -1;
  double best_ratio = 0.0;  // its ratio (0: none had min_sectors sectors)
  int best_sectors = 0;
  double largest_ratio = 0.0;  // the largest ratio of any judged mirror so far
  int swapped_a = -1;          // the swap named now (-1: none)
  int swapped_b = -1;
};

class ArrayMirrorCheck {
 public:
  // `settings` as config::check_fusion_params checks them (their bounds live there alone).
  ArrayMirrorCheck(int array_index, const doa::ArrayGeometry& geometry,
                   const MirrorCheckSettings& settings);

  // The swaps of this array that are mirrors: none means nothing to test.
  int mirrors() const { return static_cast<int>(mirrors_.size()); }
  // One DOA (unit, site frame) and the directions from the array to the reference tracks at
  // its time (unit, site frame: where the sound now arriving left each), with the array's
  // attitude. Returns true when a swap was named on this DOA (events() holds it).
  bool observe(double time_s, const Eigen::Vector3d& measured, const Eigen::Matrix3d& array_to_site,
               std::span<const Eigen::Vector3d> references);
  std::span<const MirrorSwapEvent> events() const { return events_; }
  void clear_events() { events_.clear(); }
  const MirrorCheckStatus& status() const { return status_; }
  // Whether swapping channels a and b is a mirror of this array (tested).
  bool is_mirror(int a, int b) const;

 private:
  static constexpr int kMaxMirrors = 28;  // 8 mics
  struct Mirror {
    int a = 0;
    int b = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitX();  // array frame
  };
  struct SectorEvidence {
    std::array<double, kMaxMirrors> doas{};     // forgetting-weighted count, per mirror
    std::array<double, kMaxMirrors> wired{};    // sum of misfits as wired (deg)
    std::array<double, kMaxMirrors> swapped{};  // and under the mirror
    double updated_s = 0.0;
  };
  void decay(SectorEvidence& sector, double time_s) const;
  void judge(double time_s);

  int array_;
  MirrorCheckSettings settings_;
  doa::DirectionSectors sector_of_;
  std::vector<Mirror> mirrors_;
  std::vector<SectorEvidence> sectors_;
  std::vector<MirrorSwapEvent> events_;
  MirrorCheckStatus status_;
  int doas_since_judged_ = 0;
  int previous_best_ = -1;  // the mirror over the bar at the last judgement
  int named_ = -1;
  double last_named_s_ = -1e300;
  double total_doas_ = 0.0;
  double total_updated_s_ = 0.0;
};

}  // namespace dronetrack::fusion
