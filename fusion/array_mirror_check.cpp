#include "fusion/array_mirror_check.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

namespace dronetrack::fusion {

namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;
constexpr std::size_t kMaxEvents = 8;  // a swap is named at most once per judgement

// Great-circle angle between two unit vectors, degrees (atan2: exact near 0).
double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kDegPerRad;
}

Eigen::Vector3d reflect(const Eigen::Vector3d& direction, const Eigen::Vector3d& normal) {
  return direction - 2.0 * direction.dot(normal) * normal;
}

}  // namespace

ArrayMirrorCheck::ArrayMirrorCheck(int array_index, const doa::ArrayGeometry& geometry,
                                   const MirrorCheckSettings& settings)
    : array_(array_index), settings_(settings), sector_of_(std::max(settings.sectors, 1)) {
  // A swap of a and b is a mirror when the plane bisecting them holds every other mic: then the
  // reflection through it exchanges a and b and keeps the rest, so the swapped array is the
  // reflected one (only the plane's normal matters to a direction).
  const auto& mics = geometry.mics_m;
  const int count = static_cast<int>(mics.size());
  for (int a = 0; a < count; ++a) {
    for (int b = a + 1; b < count; ++b) {
      const Eigen::Vector3d axis = mics[a] - mics[b];
      const double spacing_m = axis.norm();
      if (!(spacing_m > 0.0)) continue;
      const Eigen::Vector3d normal = axis / spacing_m;
      const Eigen::Vector3d middle = 0.5 * (mics[a] + mics[b]);
      bool mirror = true;
      for (int k = 0; k < count && mirror; ++k) {
        if (k == a || k == b) continue;
        mirror =
            std::abs((mics[k] - middle).dot(normal)) <= settings.symmetry_tolerance * spacing_m;
      }
      if (mirror && static_cast<int>(mirrors_.size()) < kMaxMirrors)
        mirrors_.push_back({a, b, normal});
    }
  }
  sectors_.assign(static_cast<std::size_t>(sector_of_.count()), SectorEvidence{});
  events_.reserve(kMaxEvents);
  status_.array = array_index;
  status_.mirrors = static_cast<int>(mirrors_.size());
}

bool ArrayMirrorCheck::is_mirror(int a, int b) const {
  return std::any_of(mirrors_.begin(), mirrors_.end(), [a, b](const Mirror& mirror) {
    return (mirror.a == a && mirror.b == b) || (mirror.a == b && mirror.b == a);
  });
}

void ArrayMirrorCheck::decay(SectorEvidence& sector, double time_s) const {
  if (time_s <= sector.updated_s) return;
  const double factor = std::exp(-(time_s - sector.updated_s) / settings_.window_s);
  for (std::size_t h = 0; h < mirrors_.size(); ++h) {
    sector.doas[h] *= factor;
    sector.wired[h] *= factor;
    sector.swapped[h] *= factor;
  }
  sector.updated_s = time_s;
}

bool ArrayMirrorCheck::observe(double time_s, const Eigen::Vector3d& measured,
                               const Eigen::Matrix3d& array_to_site,
                               std::span<const Eigen::Vector3d> references) {
  if (mirrors_.empty() || references.empty() || !settings_.enabled) return false;
  const Eigen::Vector3d doa = array_to_site.transpose() * measured;
  // Per hypothesis, the nearest reference it predicts (a mirror may match another track than the
  // wiring does: each hypothesis takes its own best, so a coincidence weighs no more than that).
  constexpr double kFar = 180.0;
  double wired_deg = kFar;
  std::array<double, kMaxMirrors> swapped_deg{};
  swapped_deg.fill(kFar);
  double best_deg = kFar;
  Eigen::Vector3d source = Eigen::Vector3d::UnitX();  // the best-explained reference (array frame)
  for (const Eigen::Vector3d& reference : references) {
    const Eigen::Vector3d to_track = array_to_site.transpose() * reference;
    const double wired = angle_deg(doa, to_track);
    wired_deg = std::min(wired_deg, wired);
    if (wired < best_deg) {
      best_deg = wired;
      source = to_track;
    }
    for (std::size_t h = 0; h < mirrors_.size(); ++h) {
      const double swapped = angle_deg(doa, reflect(to_track, mirrors_[h].normal));
      swapped_deg[h] = std::min(swapped_deg[h], swapped);
      if (swapped < best_deg) {
        best_deg = swapped;
        source = to_track;
      }
    }
  }
  // No hypothesis puts it near a track: another source, an echo or an outlier, no evidence.
  if (!(best_deg <= settings_.gate_deg)) return false;

  SectorEvidence& sector = sectors_[static_cast<std::size_t>(sector_of_.nearest(source))];
  decay(sector, time_s);
  for (std::size_t h = 0; h < mirrors_.size(); ++h) {
    // The mirror moves the source's direction by twice its angle from the plane.
    const double separation_deg =
        2.0 * std::asin(std::min(1.0, std::abs(source.dot(mirrors_[h].normal)))) * kDegPerRad;
    if (separation_deg < settings_.min_separation_deg) continue;
    sector.doas[h] += 1.0;
    sector.wired[h] += wired_deg;
    sector.swapped[h] += swapped_deg[h];
  }
  if (time_s > total_updated_s_) {
    total_doas_ *= std::exp(-(time_s - total_updated_s_) / settings_.window_s);
    total_updated_s_ = time_s;
  }
  total_doas_ += 1.0;
  status_.evidence_doas = total_doas_;
  if (++doas_since_judged_ < settings_.judge_doas) return false;
  doas_since_judged_ = 0;
  const std::size_t before = events_.size();
  judge(time_s);
  return events_.size() > before;
}

void ArrayMirrorCheck::judge(double time_s) {
  int best = -1;
  double best_ratio = 0.0;
  double best_wired = 0.0;
  double best_swapped = 0.0;
  int best_sectors = 0;
  for (SectorEvidence& sector : sectors_) decay(sector, time_s);
  for (std::size_t h = 0; h < mirrors_.size(); ++h) {
    int judged = 0;
    double wired = 0.0;
    double swapped = 0.0;
    for (const SectorEvidence& sector : sectors_) {
      if (!(sector.doas[h] >= settings_.min_sector_doas)) continue;
      ++judged;
      wired += sector.wired[h] / sector.doas[h];
      swapped += sector.swapped[h] / sector.doas[h];
    }
    if (judged < settings_.min_sectors) continue;
    wired /= judged;
    swapped /= judged;
    const double ratio = wired / std::max(swapped, settings_.floor_deg);
    if (ratio > best_ratio) {
      best = static_cast<int>(h);
      best_ratio = ratio;
      best_wired = wired;
      best_swapped = swapped;
      best_sectors = judged;
    }
  }
  status_.best_channel_a = best >= 0 ? mirrors_[static_cast<std::size_t>(best)].a : -1;
  status_.best_channel_b = best >= 0 ? mirrors_[static_cast<std::size_t>(best)].b : -1;
  status_.best_ratio = best_ratio;
  status_.best_sectors = best_sectors;
  status_.largest_ratio = std::max(status_.largest_ratio, best_ratio);

  const bool over = best >= 0 && best_ratio >= settings_.evidence_ratio;
  const bool named = over && previous_best_ == best;
  previous_best_ = over ? best : -1;
  if (!named) {
    named_ = -1;
    status_.swapped_a = status_.swapped_b = -1;
    return;
  }
  const Mirror& mirror = mirrors_[static_cast<std::size_t>(best)];
  status_.swapped_a = mirror.a;
  status_.swapped_b = mirror.b;
  if (named_ == best || time_s - last_named_s_ < settings_.rewarn_s) {
    named_ = best;
    return;
  }
  named_ = best;
  last_named_s_ = time_s;
  if (events_.size() == kMaxEvents) return;  // never allocates
  MirrorSwapEvent event;
  event.array = array_;
  event.channel_a = mirror.a;
  event.channel_b = mirror.b;
  event.time_s = time_s;
  event.wired_misfit_deg = best_wired;
  event.swapped_misfit_deg = best_swapped;
  event.evidence_ratio = best_ratio;
  event.sectors = best_sectors;
  events_.push_back(event);
}

}  // namespace dronetrack::fusion
