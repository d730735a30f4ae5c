#pragma once
// The tracker's records (FusionEngine's, shared by its stages): one track (filter, life-cycle
// bookkeeping per array, evidence), and each array's recent DOAs kept for initiation and ghost
// checks. Plain data; the stages that read and write them are named in fusion/README.md.
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>

#include <Eigen/Core>

#include "doa/doa_measurement.hpp"
#include "fusion/innovation.hpp"
#include "fusion/measurement_model.hpp"
#include "fusion/spectrum_agreement.hpp"
#include "fusion/state.hpp"
#include "fusion/track_classifier.hpp"
#include "fusion/track_filter.hpp"

namespace dronetrack::fusion {

inline constexpr int kMaxArrays = 64;               // contributing_arrays is a 64-bit mask
inline constexpr std::size_t kRecentPerArray = 64;  // recent DOAs kept per array for initiation
inline constexpr double kNeverS = -std::numeric_limits<double>::infinity();
// A DOA heard by a track within this long counts in contributing_arrays.
inline constexpr double kContributionMemoryS = 1.0;

// One recent DOA of one array, kept for initiation and ghost checks.
struct RecentDoa {
  double time_s = 0.0;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // a cone's is for display only
  DoaMeasurementModel model;                             // from its pose and ambiguity
  Measurement z = Measurement::Zero();
  MeasurementCovariance noise = MeasurementCovariance::Identity();  // R incl. floor
  bool associated = false;                                          // went to a track
  // The id of the tentative track one array alone keeps updating (held_by_one_array) that it
  // went to, else -1. That track's range is only what its first pair said, which may have been
  // a crossing with another source's ray: the DOA may still pair with another array's to start
  // a track, which then replaces that one.
  int weak_claimant_id = -1;
  bool used = false;               // started a track
  doa::AcousticFeatures acoustic;  // what its spectrum said (the track it starts tallies it)
  // Rays a triangulation may use: the direction, and its mirror image for a planar array. A
  // cone is no ray (its display direction is one point of a surface): 0.
  int image_count() const {
    switch (model.kind) {
      case MeasurementKind::azel:
        return 1;
      case MeasurementKind::mirrored_azel:
        return 2;
      case MeasurementKind::cone:
        return 0;
    }
    return 0;
  }
  Eigen::Vector3d image(int index) const {
    return index == 0 ? direction
                      : Eigen::Vector3d(direction - 2.0 * direction.dot(model.axis) * model.axis);
  }
};

class RecentRing {
 public:
  // Returns the entry's sequence number (find() takes it back while the entry is kept).
  std::uint64_t push(const RecentDoa& doa) {
    items_[(start_ + size_) % kRecentPerArray] = doa;
    if (size_ < kRecentPerArray) {
      ++size_;
    } else {
      start_ = (start_ + 1) % kRecentPerArray;
      ++first_sequence_;
    }
    return first_sequence_ + size_ - 1;
  }
  // The index of the entry pushed as `sequence`, if it is still kept.
  std::optional<std::size_t> find(std::uint64_t sequence) const {
    if (sequence < first_sequence_ || sequence >= first_sequence_ + size_) return std::nullopt;
    return static_cast<std::size_t>(sequence - first_sequence_);
  }
  // Drops entries older than `oldest_s`; returns how many left never associated nor used.
  int expire(double oldest_s) {
    int unclaimed = 0;
    while (size_ > 0 && items_[start_].time_s < oldest_s) {
      if (!items_[start_].associated && !items_[start_].used) ++unclaimed;
      start_ = (start_ + 1) % kRecentPerArray;
      --size_;
      ++first_sequence_;
    }
    return unclaimed;
  }
  std::size_t size() const { return size_; }
  RecentDoa& operator[](std::size_t i) { return items_[(start_ + i) % kRecentPerArray]; }
  RecentDoa& back() { return (*this)[size_ - 1]; }

 private:
  std::array<RecentDoa, kRecentPerArray> items_{};
  std::size_t start_ = 0;
  std::size_t size_ = 0;
  std::uint64_t first_sequence_ = 0;  // sequence number of the entry at start_
};

// An unclaimed DOA waiting to seed a track until the other arrays' DOAs of its moment are in.
struct PendingSeed {
  int array = 0;
  std::uint64_t sequence = 0;
  double time_s = 0.0;
};

struct Track {
  int id = 0;
  std::unique_ptr<TrackFilter> filter;
  double time_s = 0.0;         // the filter's state time
  double last_update_s = 0.0;  // last DOA it took
  // M-of-N history per array, newest frame of that array in bit 0. A drone is heard by a
  // subset of the arrays (the nearest, or the ones a louder drone does not mask), so the hits
  // are counted per track over the last N frames of each array: one stream of all arrays'
  // frames would count the frames of the arrays that cannot hear it as misses.
  std::array<std::uint32_t, kMaxArrays> hits_by_array{};
  bool confirmed = false;
  std::array<double, kMaxArrays> heard_by_array_s{};
  std::array<int, kMaxArrays> updates_by_array{};  // DOAs taken from each array
  Innovation innovation;                           // of the current frame
  bool innovation_ok = false;
  // The innovation's prediction as a unit vector (an azel frame's): where the sound now arriving
  // left the track, seen from the frame's array.
  Eigen::Vector3d predicted_direction = Eigen::Vector3d::UnitX();
  double inflation = 1.0;  // of this frame's DOA covariance (correlated errors)
  TrackEvidence evidence;  // drone or not
  std::array<AcousticTally, kMaxArrays> acoustic_by_array{};
  double confirmed_at_s = 0.0;
  // Since when it has been a duplicate along a sharper track's ray (duplicate_along_ray), else
  // kNeverS.
  double duplicate_since_s = kNeverS;
  // The arrays whose DOAs started it (a pair and the arrays agreeing then; bit per array): what
  // each array gave it since is its updates less that one.
  std::uint64_t birth_arrays = 0;
  // Started from one array's DOAs (issue 15) and not yet handed to the default filter: its
  // range rests on hypotheses or the platform's motion, not on a triangulation.
  bool one_array = false;
  int origin_array = -1;                                                   // its one array
  MeasurementCovariance origin_noise = MeasurementCovariance::Identity();  // of its first DOA
  int branches_left = -1;  // a Gaussian sum's locus branches (mirror sides) with weight left
  // DOAs it took (tentative) in frames that held no more DOAs than the confirmed tracks their
  // array hears: the slot of a confirmed track's DOA, which an outlier had taken.
  int crowded_updates = 0;
  // Manoeuvre onset: per array (bit set: valid), the last DOA beyond the gate that no track took
  // but a manoeuvre could explain, as its residual from the prediction, its R and its time.
  std::uint64_t unexplained_arrays = 0;
  std::array<double, kMaxArrays> unexplained_s{};
  std::array<Measurement, kMaxArrays> unexplained_residual{};
  std::array<MeasurementCovariance, kMaxArrays> unexplained_noise{};
};

}  // namespace dronetrack::fusion
