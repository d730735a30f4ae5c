#include "doa/pose_track.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "doa/ls_doa_solver.hpp"

namespace dronetrack::doa {

namespace {

bool finite(const PoseSample& sample) {
  return std::isfinite(sample.time_s) && sample.position_m.allFinite() &&
         std::isfinite(sample.yaw_deg) && std::isfinite(sample.pitch_deg) &&
         std::isfinite(sample.roll_deg);
}

// The tangent-plane covariance of a unit direction from its (azimuth, elevation) covariance:
// G C G^T with G = d u / d(az, el), the inverse of azel_covariance_from_direction's Jacobian.
Eigen::Matrix3d direction_covariance_from_azel(const Eigen::Vector3d& u,
                                               const Eigen::Matrix2d& azel_covariance) {
  const double azimuth = std::atan2(u.y(), u.x());
  const double elevation = std::asin(std::clamp(u.z(), -1.0, 1.0));
  Eigen::Matrix<double, 3, 2> jacobian;
  jacobian << -std::cos(elevation) * std::sin(azimuth), -std::sin(elevation) * std::cos(azimuth),
      std::cos(elevation) * std::cos(azimuth), -std::sin(elevation) * std::sin(azimuth), 0.0,
      std::cos(elevation);
  return jacobian * azel_covariance * jacobian.transpose();
}

}  // namespace

PoseStamp fixed_stamp(const ArrayGeometry& geometry) {
  PoseStamp stamp;
  stamp.centre_m = geometry.centre_site_m();
  stamp.array_to_site = Eigen::Quaterniond(geometry.array_to_site());
  stamp.moving = false;
  return stamp;
}

Eigen::Quaterniond pose_attitude(const PoseSample& sample) {
  return Eigen::Quaterniond(attitude_to_site(sample.yaw_deg, sample.pitch_deg, sample.roll_deg));
}

Eigen::Vector3d mic_centroid_m(const ArrayGeometry& geometry) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& mic : geometry.mics_m) centroid += mic;
  if (!geometry.mics_m.empty()) centroid /= static_cast<double>(geometry.mics_m.size());
  return centroid;
}

PoseStamp interpolate_pose(const PoseSample& before, const PoseSample& after, double time_s,
                           const Eigen::Vector3d& mic_centroid_array_m) {
  const double span_s = after.time_s - before.time_s;
  const double fraction =
      span_s > 0.0 ? std::clamp((time_s - before.time_s) / span_s, 0.0, 1.0) : 0.0;
  PoseStamp stamp;
  // Eigen's slerp takes the shorter arc (it flips q to -q when their dot is negative), so a
  // heading from 179 to -179 deg passes through 180, not through 0.
  stamp.array_to_site = pose_attitude(before).slerp(fraction, pose_attitude(after)).normalized();
  const Eigen::Vector3d origin_m =
      before.position_m + fraction * (after.position_m - before.position_m);
  stamp.centre_m = origin_m + stamp.array_to_site * mic_centroid_array_m;
  stamp.moving = true;
  return stamp;
}

PoseTrack::PoseTrack(std::vector<PoseSample> samples) : samples_(std::move(samples)) {
  if (samples_.size() < 2)
    throw std::invalid_argument("a pose track needs at least 2 samples, got " +
                                std::to_string(samples_.size()));
  for (std::size_t i = 0; i < samples_.size(); ++i) {
    if (!finite(samples_[i]))
      throw std::invalid_argument("pose sample " + std::to_string(i) + " is not finite");
    if (i > 0 && !(samples_[i].time_s > samples_[i - 1].time_s))
      throw std::invalid_argument("pose sample " + std::to_string(i) +
                                  ": times must strictly increase");
  }
}

std::size_t PoseTrack::after(double time_s) const {
  // The first sample after time_s; time_s == end_s() takes the last interval.
  const auto found =
      std::upper_bound(samples_.begin(), samples_.end(), time_s,
                       [](double t, const PoseSample& sample) { return t < sample.time_s; });
  return std::min(static_cast<std::size_t>(found - samples_.begin()), samples_.size() - 1);
}

std::optional<PoseStamp> PoseTrack::stamp(double time_s, const ArrayGeometry& geometry) const {
  if (!covers(time_s)) return std::nullopt;
  const std::size_t next = after(time_s);
  return interpolate_pose(samples_[next - 1], samples_[next], time_s, mic_centroid_m(geometry));
}

std::optional<Eigen::Vector3d> PoseTrack::velocity_mps(double time_s) const {
  if (!covers(time_s)) return std::nullopt;
  const std::size_t next = after(time_s);
  const PoseSample& before = samples_[next - 1];
  const PoseSample& later = samples_[next];
  return Eigen::Vector3d((later.position_m - before.position_m) / (later.time_s - before.time_s));
}

bool PoseRing::push(const PoseSample& sample) {
  if (!finite(sample) || (count_ > 0 && !(sample.time_s > newest_s()))) {
    ++refused_;
    return false;
  }
  if (count_ == kCapacity) {
    first_ = (first_ + 1) % kCapacity;
    --count_;
  }
  samples_[(first_ + count_) % kCapacity] = sample;
  ++count_;
  return true;
}

double PoseRing::newest_s() const {
  return count_ == 0 ? -std::numeric_limits<double>::infinity() : at(count_ - 1).time_s;
}

std::optional<PoseStamp> PoseRing::stamp(double time_s,
                                         const Eigen::Vector3d& mic_centroid_array_m) const {
  if (count_ < 2 || !(time_s >= at(0).time_s) || !(time_s <= newest_s())) return std::nullopt;
  // Binary search on ring positions for the first sample after time_s.
  std::size_t low = 1;
  std::size_t high = count_ - 1;
  while (low < high) {
    const std::size_t middle = (low + high) / 2;
    if (at(middle).time_s > time_s)
      high = middle;
    else
      low = middle + 1;
  }
  const PoseSample& before = at(low - 1);
  const PoseSample& after = at(low);
  if (after.time_s - before.time_s > max_gap_s_) return std::nullopt;
  if (std::abs(wrap_deg_180(after.yaw_deg - before.yaw_deg)) > kMaxPoseYawStep_deg)
    return std::nullopt;
  return interpolate_pose(before, after, time_s, mic_centroid_array_m);
}

void restamp(DoaMeasurement& measurement, const PoseStamp& stamp,
             const Eigen::Matrix3d& solved_array_to_site) {
  const Eigen::Matrix3d turn =
      stamp.array_to_site.toRotationMatrix() * solved_array_to_site.transpose();
  const Eigen::Vector3d direction = measurement.direction.normalized();
  Eigen::Matrix3d covariance =
      turn * direction_covariance_from_azel(direction, measurement.azel_covariance_rad2) *
      turn.transpose();
  Eigen::Vector3d turned = turn * direction;
  // A full direction has no axis to turn.
  Eigen::Vector3d axis = measurement.ambiguity == DoaAmbiguity::none
                             ? measurement.ambiguity_axis
                             : Eigen::Vector3d(turn * measurement.ambiguity_axis);
  if (measurement.ambiguity == DoaAmbiguity::mirror_up_down && axis.z() < 0.0) {
    // The platform tilted past the vertical: the image above the plane is the other one.
    const Eigen::Matrix3d mirror = Eigen::Matrix3d::Identity() - 2.0 * axis * axis.transpose();
    turned = mirror * turned;
    covariance = mirror * covariance * mirror.transpose();
    axis = -axis;
  }
  if (measurement.ambiguity == DoaAmbiguity::cone) {
    // The cone's display point is its horizontal one (as the solver reports it): turn the
    // turned point about the turned axis to there; the covariance, symmetric about the axis up
    // to that turn, goes with it.
    const Eigen::Vector3d unit_axis = axis.normalized();
    const Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(unit_axis);
    if (across.norm() > 1e-9) {
      const double cosine = std::clamp(turned.dot(unit_axis), -1.0, 1.0);
      const Eigen::Vector3d target =
          unit_axis * cosine + across.normalized() * std::sqrt(1.0 - cosine * cosine);
      const double angle =
          std::atan2(unit_axis.dot(turned.cross(target)), turned.dot(target) - cosine * cosine);
      const Eigen::Matrix3d about_axis = Eigen::AngleAxisd(angle, unit_axis).toRotationMatrix();
      turned = about_axis * turned;
      covariance = about_axis * covariance * about_axis.transpose();
    }
  }
  measurement.direction = turned.normalized();
  measurement.azel_covariance_rad2 =
      azel_covariance_from_direction(measurement.direction, covariance);
  measurement.ambiguity_axis = axis.normalized();
  measurement.pose = stamp;
}

}  // namespace dronetrack::doa
