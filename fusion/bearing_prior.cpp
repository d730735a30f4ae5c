#include "fusion/bearing_prior.hpp"

#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

namespace dronetrack::fusion {
namespace {
constexpr double kParallelTolerance = 1e-6;

Eigen::Vector3d direction_of_azel(const Measurement& azel) {
  return {std::cos(azel(1)) * std::cos(azel(0)), std::cos(azel(1)) * std::sin(azel(0)),
          std::sin(azel(1))};
}
}  // namespace

std::optional<BearingLocus> bearing_locus(const DoaMeasurementModel& model, const Measurement& z,
                                          double angle_std_rad,
                                          const Eigen::Vector3d& hint_direction,
                                          std::optional<double> source_plane_z_m) {
  BearingLocus locus;
  locus.model = model;
  locus.z = z;
  locus.angle_std_rad = angle_std_rad;
  locus.hint_direction = hint_direction;
  locus.source_plane_z_m = source_plane_z_m;
  switch (model.kind) {
    case MeasurementKind::azel:
      locus.branch_count = 1;
      break;
    case MeasurementKind::mirrored_azel: {
      // With a plane only the azimuth counts: a horizontal array plane's mirror images share it.
      const Eigen::Vector3d u = direction_of_azel(z);
      const Eigen::Vector3d mirror = u - 2.0 * u.dot(model.axis) * model.axis;
      const bool same_azimuth =
          std::abs(azel_residual(azel_of(u), azel_of(mirror))(0)) < kParallelTolerance;
      locus.branch_count = source_plane_z_m && same_azimuth ? 1 : 2;
      break;
    }
    case MeasurementKind::cone:
      if (!source_plane_z_m) return std::nullopt;
      if (model.axis.cross(Eigen::Vector3d::UnitZ()).norm() < kParallelTolerance)
        return std::nullopt;
      locus.branch_count = 2;
      break;
  }
  return locus;
}

std::optional<Eigen::Vector3d> BearingLocus::offset_at(int branch, double range_m) const {
  const auto offset = offset_anywhere(branch, range_m);
  if (!offset || model.centre_m.z() + offset->z() < min_altitude_m) return std::nullopt;
  return offset;
}

std::optional<Eigen::Vector3d> BearingLocus::offset_anywhere(int branch, double range_m) const {
  if (branch < 0 || branch >= branch_count || !(range_m > 0.0)) return std::nullopt;
  if (model.kind == MeasurementKind::cone) {
    // d = alpha e + beta a + t n with e = z-hat, a the axis, n = (a x e) / |a x e|:
    // e . d = h and a . d = r cos(theta) fix alpha and beta, |d| = r fixes t up to its sign.
    const Eigen::Vector3d e = Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d& a = model.axis;
    const double g = a.dot(e);
    const double h = *source_plane_z_m - model.centre_m.z();
    const double k = range_m * std::cos(z(0));
    const double beta = (k - g * h) / (1.0 - g * g);
    const double alpha = h - beta * g;
    const Eigen::Vector3d d0 = alpha * e + beta * a;
    const double t2 = range_m * range_m - d0.squaredNorm();
    if (!(t2 >= 0.0)) return std::nullopt;
    const Eigen::Vector3d n = a.cross(e).normalized();
    return Eigen::Vector3d(d0 + (branch == 0 ? 1.0 : -1.0) * std::sqrt(t2) * n);
  }
  Eigen::Vector3d u = direction_of_azel(z);
  if (branch == 1) u -= 2.0 * u.dot(model.axis) * model.axis;  // the mirror image
  if (!source_plane_z_m) return Eigen::Vector3d(range_m * u);
  // On the plane along the measured azimuth.
  const double h = *source_plane_z_m - model.centre_m.z();
  const double horizontal2 = range_m * range_m - h * h;
  const Eigen::Vector2d heading = u.head<2>();
  if (!(horizontal2 >= 0.0) || heading.norm() < kParallelTolerance) return std::nullopt;
  const Eigen::Vector2d along = heading.normalized() * std::sqrt(horizontal2);
  return Eigen::Vector3d(along.x(), along.y(), h);
}

int BearingLocus::preferred_branch(double range_m) const {
  int best = 0;
  double best_distance = std::numeric_limits<double>::infinity();
  for (int branch = 0; branch < branch_count; ++branch) {
    const auto offset = offset_at(branch, range_m);
    if (!offset) continue;
    const double distance = (offset->normalized() - hint_direction).norm();
    if (distance < best_distance) {
      best_distance = distance;
      best = branch;
    }
  }
  return best;
}

Eigen::Matrix3d range_bearing_covariance(const Eigen::Vector3d& offset, double range_std_m,
                                         double angle_std_rad) {
  const double range = offset.norm();
  const Eigen::Vector3d u = offset / range;
  const Eigen::Matrix3d radial = u * u.transpose();
  const double across = range * angle_std_rad;
  return range_std_m * range_std_m * radial +
         across * across * (Eigen::Matrix3d::Identity() - radial);
}

void state_at(const Eigen::Vector3d& position, const Eigen::Matrix3d& position_covariance,
              const OneArrayParams& params, StateVector& mean, StateCovariance& covariance) {
  mean.setZero();
  mean.segment<3>(StateBlock::position) = position;
  covariance.setZero();
  covariance.block<3, 3>(StateBlock::position, StateBlock::position) = position_covariance;
  covariance.block<3, 3>(StateBlock::velocity, StateBlock::velocity) =
      Eigen::Matrix3d::Identity() * params.velocity_std_mps * params.velocity_std_mps;
  covariance.block<3, 3>(StateBlock::acceleration, StateBlock::acceleration) =
      Eigen::Matrix3d::Identity() * params.acceleration_std_mps2 * params.acceleration_std_mps2;
}

bool constrain_to_plane(StateVector& mean, StateCovariance& covariance, double plane_z_m,
                        double plane_std_m) {
  constexpr std::array<int, 3> kVertical{StateBlock::position + 2, StateBlock::velocity + 2,
                                         StateBlock::acceleration + 2};
  Eigen::Matrix<double, 3, kStateSize> h = Eigen::Matrix<double, 3, kStateSize>::Zero();
  for (int row = 0; row < 3; ++row) h(row, kVertical[row]) = 1.0;
  const Eigen::Vector3d target(plane_z_m, 0.0, 0.0);
  const Eigen::Matrix3d r = Eigen::Vector3d::Constant(plane_std_m * plane_std_m).asDiagonal();
  const Eigen::Matrix<double, kStateSize, 3> cross = covariance * h.transpose();
  const Eigen::Matrix3d s = h * cross + r;
  const Eigen::Matrix<double, kStateSize, 3> gain = cross * s.inverse();
  StateVector constrained = mean + gain * (target - h * mean);
  // Joseph form: the vertical variances collapse by orders of magnitude, the short form loses
  // symmetry and definiteness.
  const StateCovariance keep = StateCovariance::Identity() - gain * h;
  StateCovariance updated = keep * covariance * keep.transpose() + gain * r * gain.transpose();
  updated = 0.5 * (updated + updated.transpose()).eval();
  if (!constrained.allFinite() || !updated.allFinite()) return false;
  mean = constrained;
  covariance = updated;
  return true;
}

}  // namespace dronetrack::fusion
