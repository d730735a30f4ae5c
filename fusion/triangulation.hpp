#pragma once
// Triangulation of N >= 2 DOA rays (SPEC 4.4).
//
// Least squares in 3-D: the point minimising sum_k |W_k^(1/2) (I - u_k u_k^T)(p - c_k)|^2,
//   p = (sum_k W_k (I - u_k u_k^T))^-1 sum_k W_k (I - u_k u_k^T) c_k,
// where W_k is the inverse covariance of the ray's perpendicular displacement at the point's range
// r_k (angular covariance of the DOA scaled by r_k^2). r_k depends on p, so the weights are
// refined over a few passes. Cov(p) = (sum_k W_k)^-1; its condition number says how well the rays
// cross (rays nearly parallel: the target is near the line through the arrays).
//
// The seed's method (seed 002 eqs. 12-13) projects two rays onto the x-y plane, intersects the
// lines and averages the two heights; kept for comparison. It fails near the array line.
#include <optional>
#include <span>

#include <Eigen/Core>

#include "fusion/fusion_params.hpp"
#include "fusion/state.hpp"

namespace dronetrack::fusion {

struct Ray {
  Eigen::Vector3d origin_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // unit
  MeasurementCovariance azel_covariance_rad2 = MeasurementCovariance::Identity() * 1e-4;
};

struct Triangulation {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_m2 = Eigen::Matrix3d::Identity();
  double condition_number = 1.0;  // of the normal matrix sum W_k (I - u u^T)
  // sum over rays of the squared Mahalanobis angle residual; chi-square with 2N - 3 dof.
  double chi_square = 0.0;
  bool in_front = true;  // the point lies ahead of every array along its ray
};

// Empty when fewer than two rays or (numerically) parallel rays.
std::optional<Triangulation> triangulate_least_squares(std::span<const Ray> rays);
// Uses the first two rays only.
std::optional<Triangulation> triangulate_seed_xy(std::span<const Ray> rays);
std::optional<Triangulation> triangulate(std::span<const Ray> rays, TriangulationMethod method);

// Quantile of the chi-square distribution: x with P(chi2_k <= x) = probability.
double chi_square_quantile(double probability, int degrees_of_freedom);

}  // namespace dronetrack::fusion
