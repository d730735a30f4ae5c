#include "doa/source_tracks.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace dronetrack::doa {

namespace {
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * kRadToDeg;
}
}  // namespace

SourceTracks::SourceTracks(int pair_count, int max_tracks, const TdoaTrackerSettings& settings,
                           double association_gate_deg)
    : pair_count_(pair_count),
      delay_s_(std::max(0, settings.regression_delay_frames) * settings.hop_s),
      max_age_s_((std::max(4, settings.regression_window_frames) + 0.5) * settings.hop_s),
      max_angular_rate_dps_(settings.max_angular_rate_dps),
      hop_s_(settings.hop_s),
      association_gate_deg_(association_gate_deg) {
  tracks_.reserve(static_cast<std::size_t>(std::max(1, max_tracks)));
  for (int k = 0; k < std::max(1, max_tracks); ++k) tracks_.emplace_back(pair_count, settings);
  observation_taken_.resize(tracks_.size() * 2 + 8, 0);
}

int SourceTracks::live_tracks() const {
  return static_cast<int>(
      std::count_if(tracks_.begin(), tracks_.end(), [](const Track& t) { return t.live; }));
}

double SourceTracks::gate_deg(int slot, double time_s) const {
  const Track& track = tracks_[static_cast<std::size_t>(slot)];
  return association_gate_deg_ + max_angular_rate_dps_ * std::max(0.0, time_s - track.last_time_s);
}

bool SourceTracks::followable(int slot, double time_s) const {
  const Track& track = tracks_[static_cast<std::size_t>(slot)];
  // Half a hop of slack for the frame times' rounding.
  return track.live && time_s - track.last_time_s <= 1.5 * hop_s_;
}

int SourceTracks::update(double time_s, std::span<const SourceObservation> observations,
                         std::span<SourceEstimate> out) {
  const std::size_t observation_count = std::min(observations.size(), observation_taken_.size());
  std::fill(observation_taken_.begin(), observation_taken_.end(), 0);
  for (Track& track : tracks_) {
    track.observation = -1;
    // A track unheard for a whole window has nothing left to fit: its slot is free again.
    if (track.live && time_s - track.last_time_s > max_age_s_) {
      track.live = false;
      track.regression.clear();
    }
  }
  // Greedy, strongest observation first: each takes the nearest live track within its gate.
  for (std::size_t o = 0; o < observation_count; ++o) {
    int best = -1;
    double best_angle = 0.0;
    for (std::size_t k = 0; k < tracks_.size(); ++k) {
      const Track& track = tracks_[k];
      if (!track.live || track.observation >= 0) continue;
      const double gate = gate_deg(static_cast<int>(k), time_s);
      const double angle = angle_deg(observations[o].direction_site, track.direction_site);
      if (angle <= gate && (best < 0 || angle < best_angle)) {
        best = static_cast<int>(k);
        best_angle = angle;
      }
    }
    if (best < 0) continue;
    tracks_[static_cast<std::size_t>(best)].observation = static_cast<int>(o);
    observation_taken_[o] = 1;
  }
  // Observations no track claimed start tracks in free slots (none free: dropped this frame).
  for (std::size_t o = 0; o < observation_count; ++o) {
    if (observation_taken_[o]) continue;
    const auto free_slot =
        std::find_if(tracks_.begin(), tracks_.end(), [](const Track& t) { return !t.live; });
    if (free_slot == tracks_.end()) break;
    free_slot->live = true;
    ++free_slot->generation;
    free_slot->regression.clear();
    free_slot->observation = static_cast<int>(o);
  }
  int count = 0;
  const PairTdoa absent{};
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    Track& track = tracks_[k];
    if (!track.live) continue;
    const SourceObservation* observation =
        track.observation >= 0 ? &observations[static_cast<std::size_t>(track.observation)]
                               : nullptr;
    if (observation != nullptr) {
      track.direction_site = observation->direction_site;
      track.last_time_s = time_s;
      for (int p = 0; p < pair_count_; ++p)
        track.regression.add(p, time_s, observation->tdoas[static_cast<std::size_t>(p)]);
    }
    if (count >= static_cast<int>(out.size())) continue;
    SourceEstimate& estimate = out[static_cast<std::size_t>(count)];
    int pairs_used = 0;
    double peak_sum = 0.0;
    for (int p = 0; p < pair_count_; ++p) {
      const PairTdoa& current =
          observation != nullptr ? observation->tdoas[static_cast<std::size_t>(p)] : absent;
      PairTdoa& smoothed = estimate.tdoas[static_cast<std::size_t>(p)];
      smoothed = track.regression.estimate(p, time_s, current);
      if (smoothed.variance_s2 > 0.0) {
        ++pairs_used;
        peak_sum += smoothed.peak_value;
      }
    }
    if (pairs_used == 0) continue;
    estimate.strength = peak_sum / pairs_used;
    estimate.track = static_cast<int>(k);
    ++count;
  }
  std::sort(out.begin(), out.begin() + count, [](const SourceEstimate& a, const SourceEstimate& b) {
    return a.strength > b.strength;
  });
  return count;
}

}  // namespace dronetrack::doa
