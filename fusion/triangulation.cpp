#include "fusion/triangulation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "fusion/measurement_model.hpp"

namespace dronetrack::fusion {
namespace {

constexpr int kRefinePasses = 3;
// Keeps the azimuth weight finite for rays straight up (cos(el) -> 0).
constexpr double kMinCosElevation = 1e-3;
// Perpendicular floor (relative) so a zero covariance cannot produce an infinite weight.
constexpr double kMinAngleStdRad = 1e-6;

// Inverse covariance of the perpendicular displacement of a ray at range r: the az/el angular
// covariance maps through the unit tangents e_az (scaled by cos el) and e_el.
Eigen::Matrix3d perpendicular_weight(const Ray& ray, double range_m) {
  const Measurement azel = azel_of(ray.direction);
  const double az = azel(0);
  const double el = azel(1);
  Eigen::Matrix<double, 3, 2> tangents;
  tangents.col(0) << -std::sin(az), std::cos(az), 0.0;
  tangents.col(1) << -std::sin(el) * std::cos(az), -std::sin(el) * std::sin(az), std::cos(el);
  const double cos_el = std::max(std::cos(el), kMinCosElevation);
  Eigen::Matrix2d scale = Eigen::Matrix2d::Zero();
  scale(0, 0) = cos_el * range_m;
  scale(1, 1) = range_m;
  Eigen::Matrix2d displacement = scale * ray.azel_covariance_rad2 * scale;
  displacement += Eigen::Matrix2d::Identity() * std::pow(kMinAngleStdRad * range_m, 2);
  return tangents * displacement.inverse() * tangents.transpose();
}

void score(std::span<const Ray> rays, Triangulation& result) {
  result.chi_square = 0.0;
  result.in_front = true;
  for (const Ray& ray : rays) {
    const Eigen::Vector3d to_point = result.position_m - ray.origin_m;
    if (to_point.dot(ray.direction) <= 0.0) result.in_front = false;
    const Measurement residual = azel_residual(azel_of(ray.direction), azel_of(to_point));
    result.chi_square += residual.dot(ray.azel_covariance_rad2.ldlt().solve(residual));
  }
}

}  // namespace

std::optional<Triangulation> triangulate_least_squares(std::span<const Ray> rays) {
  if (rays.size() < 2) return std::nullopt;
  Triangulation result;
  // First pass at unit range: equal weight per radian, which only needs the directions.
  std::array<double, 64> ranges{};
  const std::size_t count = std::min<std::size_t>(rays.size(), ranges.size());
  std::fill(ranges.begin(), ranges.end(), 1.0);
  for (int pass = 0; pass < kRefinePasses; ++pass) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < count; ++k) {
      const Eigen::Matrix3d weight = perpendicular_weight(rays[k], ranges[k]);
      normal += weight;  // W_k (I - u u^T) = W_k: W_k already lives in the perpendicular plane
      rhs += weight * rays[k].origin_m;
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(normal);
    const Eigen::Vector3d values = eigen.eigenvalues();
    if (!(values(0) > values(2) * 1e-14) || !std::isfinite(values(2))) return std::nullopt;
    result.condition_number = values(2) / values(0);
    result.position_m = normal.ldlt().solve(rhs);
    result.covariance_m2 = eigen.eigenvectors() * values.cwiseInverse().asDiagonal() *
                           eigen.eigenvectors().transpose();
    for (std::size_t k = 0; k < count; ++k) {
      // A point behind an array still gets a finite range so the next pass stays defined.
      ranges[k] = std::max((result.position_m - rays[k].origin_m).norm(), 1e-3);
    }
  }
  if (!result.position_m.allFinite()) return std::nullopt;
  score(rays.first(count), result);
  return result;
}

std::optional<Triangulation> triangulate_seed_xy(std::span<const Ray> rays) {
  if (rays.size() < 2) return std::nullopt;
  const Ray& a = rays[0];
  const Ray& b = rays[1];
  // Solve c_a + s d_a = c_b + t d_b in the x-y plane (seed 002 eq. 12).
  const Eigen::Vector2d da = a.direction.head<2>();
  const Eigen::Vector2d db = b.direction.head<2>();
  Eigen::Matrix2d system;
  system.col(0) = da;
  system.col(1) = -db;
  const double determinant = system.determinant();
  if (std::abs(determinant) < 1e-12 * da.norm() * db.norm() || da.norm() < 1e-9 ||
      db.norm() < 1e-9) {
    return std::nullopt;
  }
  const Eigen::Vector2d steps = system.inverse() * (b.origin_m.head<2>() - a.origin_m.head<2>());
  const Eigen::Vector2d xy = a.origin_m.head<2>() + steps(0) * da;
  // Heights: each ray's height at its horizontal distance to the point, averaged (eq. 13).
  const auto height_along = [&xy](const Ray& ray) {
    const double horizontal = (xy - ray.origin_m.head<2>()).norm();
    const double tan_el = ray.direction.z() / std::max(ray.direction.head<2>().norm(), 1e-9);
    return ray.origin_m.z() + horizontal * tan_el;
  };
  Triangulation result;
  result.position_m << xy, 0.5 * (height_along(a) + height_along(b));
  // The seed gives no covariance; the LS one at this point is the honest stand-in.
  if (auto least_squares = triangulate_least_squares(rays.first(2))) {
    result.covariance_m2 = least_squares->covariance_m2;
    result.condition_number = least_squares->condition_number;
  }
  score(rays.first(2), result);
  if (!result.position_m.allFinite()) return std::nullopt;
  return result;
}

std::optional<Triangulation> triangulate(std::span<const Ray> rays, TriangulationMethod method) {
  return method == TriangulationMethod::seed_xy_projection ? triangulate_seed_xy(rays)
                                                           : triangulate_least_squares(rays);
}

double chi_square_quantile(double probability, int degrees_of_freedom) {
  const double p = std::clamp(probability, 1e-12, 1.0 - 1e-12);
  const int k = std::max(degrees_of_freedom, 1);
  if (k == 2) return -2.0 * std::log(1.0 - p);
  // Upper tail in closed form for integer dof; bisection on it (monotone).
  const auto upper_tail = [k](double x) {
    const double half = 0.5 * x;
    double sum = 0.0;
    double term = 0.0;
    if (k % 2 == 0) {
      term = 1.0;
      for (int i = 0; i < k / 2; ++i) {
        if (i > 0) term *= half / i;
        sum += term;
      }
      return std::exp(-half) * sum;
    }
    term = std::sqrt(2.0 * x / std::numbers::pi);
    for (int i = 0; i < (k - 1) / 2; ++i) {
      if (i > 0) term *= x / (2.0 * i + 1.0);
      sum += term;
    }
    return std::erfc(std::sqrt(half)) + std::exp(-half) * sum;
  };
  double low = 0.0;
  double high = 10.0 * k + 100.0;
  for (int i = 0; i < 200; ++i) {
    const double middle = 0.5 * (low + high);
    (upper_tail(middle) > 1.0 - p ? low : high) = middle;
  }
  return 0.5 * (low + high);
}

}  // namespace dronetrack::fusion
