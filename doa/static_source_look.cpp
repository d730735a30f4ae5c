#include "doa/static_source_look.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

namespace {
double radians(double degrees) { return degrees * std::numbers::pi / 180.0; }
}  // namespace

StaticSourceLook::StaticSourceLook(const GccPhat& gcc, double hop_s, int max_sources,
                                   const StaticLookSettings& settings)
    : settings_(settings),
      keep_share_(std::exp(-hop_s / settings.averaging_time_s)),
      drift_cosine_(std::cos(radians(settings.max_drift_deg))),
      min_elevation_sine_(std::sin(radians(settings.min_elevation_deg))),
      average_(static_cast<std::size_t>(gcc.pair_count()) * gcc.phasors(0).size()),
      // Up to max_looks looks and a follow() a frame over 2 hold_s, and one frame more: the
      // oldest wanted is still there.
      looks_((static_cast<std::size_t>(std::ceil(2.0 * settings.hold_s / hop_s)) + 2) *
             static_cast<std::size_t>(settings.max_looks + 1)),
      found_((static_cast<std::size_t>(std::ceil(settings.own_look_memory_s / hop_s)) + 2) *
             static_cast<std::size_t>(max_sources)) {}

void StaticSourceLook::accumulate(const GccPhat& gcc) {
  ++frame_;
  const std::size_t bins = gcc.phasors(0).size();
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const std::span<const std::complex<double>> frame = gcc.phasors(p);
    std::complex<double>* average = average_.data() + static_cast<std::size_t>(p) * bins;
    // A complex times a real is two products: the rows as doubles.
    simd::exponential_average({reinterpret_cast<const double*>(frame.data()),
                               reinterpret_cast<double*>(average), 2 * bins, keep_share_});
  }
}

void StaticSourceLook::load_average(GccPhat& gcc, std::span<const std::uint8_t> keep) const {
  gcc.cross_power_from(average_, keep);
}

void StaticSourceLook::load_average(GccPhat& gcc, std::span<const std::uint8_t> keep,
                                    const BinOwners& owners) const {
  gcc.cross_power_from(average_, keep, owners);
}

void StaticSourceLook::note_found(double time_s, std::span<const Eigen::Vector3d> directions_site) {
  for (const Eigen::Vector3d& direction : directions_site) {
    found_[next_found_] = {time_s, direction};
    next_found_ = (next_found_ + 1) % found_.size();
  }
}

bool StaticSourceLook::explained(double time_s, const Eigen::Vector3d& direction_site,
                                 double separation_cosine) const {
  for (const Look& look : found_)
    if (time_s - look.time_s <= settings_.own_look_memory_s + 1e-6 &&
        look.direction.dot(direction_site) >= separation_cosine)
      return true;
  return false;
}

bool StaticSourceLook::held(double time_s, const Eigen::Vector3d& direction_site) {
  bool static_direction = false;
  for (const Look& look : looks_) {
    const double age_s = time_s - look.time_s;
    // A microsecond's slack at both ends: frame times are sums of sample counts over the rate.
    if (age_s >= settings_.hold_s - 1e-6 && age_s <= 2.0 * settings_.hold_s + 1e-6 &&
        look.direction.dot(direction_site) >= drift_cosine_)
      static_direction = true;
  }
  looks_[next_look_] = {time_s, direction_site};
  next_look_ = (next_look_ + 1) % looks_.size();
  return static_direction && direction_site.z() >= min_elevation_sine_;
}

void StaticSourceLook::hold(const Eigen::Vector3d& direction_site) {
  held_direction_ = direction_site;
  holding_ = true;
}

bool StaticSourceLook::follow(double time_s, const Eigen::Vector3d& direction_site,
                              double separation_cosine) {
  // Against the direction the search held, not the last frame's: a frame-to-frame test would
  // let a mover walk the hold away. One frame's measurement under the louder sources scatters
  // more than the average's direction (by 2 deg on the known-answer test): the same source is
  // what the node calls the same source anywhere (srp_min_separation_deg).
  if (holding_ && direction_site.dot(held_direction_) >= separation_cosine &&
      direction_site.z() >= min_elevation_sine_) {
    // The held direction is what the look holds (held() of a later search compares with it).
    looks_[next_look_] = {time_s, held_direction_};
    next_look_ = (next_look_ + 1) % looks_.size();
    return true;
  }
  lose();
  return false;
}

void StaticSourceLook::lose() {
  if (holding_) lost_frame_ = frame_;
  holding_ = false;
}

bool StaticSourceLook::search_due() const {
  return frame_ % settings_.search_every_frames == 0 ||
         frame_ - lost_frame_ <= settings_.search_every_frames;
}

void StaticSourceLook::reset() {
  std::fill(looks_.begin(), looks_.end(), Look{});
  holding_ = false;
}

}  // namespace dronetrack::doa
