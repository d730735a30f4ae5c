#include "doa/ls_doa_solver.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

namespace dronetrack::doa {

namespace {
// Geometry axes weaker than this fraction of the strongest carry no direction information.
constexpr double kRankTolerance = 1e-4;
// Near the array plane (planar arrays) or the cone's axis the angle Jacobian blows up; this
// floor keeps the propagated covariance finite and conservative.
constexpr double kMinLever = 0.05;
// Variance given to a direction the geometry cannot resolve (the cone's free angle): (90 deg)^2.
constexpr double kUnresolvedVariance = (std::numbers::pi / 2.0) * (std::numbers::pi / 2.0);

int rank_of_scatter(const Eigen::Vector3d& ascending_eigenvalues) {
  int rank = 0;
  for (int axis = 0; axis < 3; ++axis)
    rank += ascending_eigenvalues(axis) > kRankTolerance * ascending_eigenvalues(2) ? 1 : 0;
  return rank;
}
}  // namespace

int direction_rank(const std::vector<Eigen::Vector3d>& mics_m) {
  // The scatter of the pair baselines, as the solver weighs them (the 1/c scale does not change
  // the rank).
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < mics_m.size(); ++i)
    for (std::size_t j = i + 1; j < mics_m.size(); ++j)
      scatter += (mics_m[i] - mics_m[j]) * (mics_m[i] - mics_m[j]).transpose();
  if (!(scatter.trace() > 0.0)) return 0;
  return rank_of_scatter(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvalues());
}

Eigen::Matrix2d azel_covariance_from_direction(const Eigen::Vector3d& u,
                                               const Eigen::Matrix3d& covariance) {
  const double horizontal2 = std::max(u.x() * u.x() + u.y() * u.y(), 1e-12);
  const double horizontal = std::sqrt(horizontal2);
  Eigen::Matrix<double, 2, 3> jacobian;
  // az = atan2(u_y, u_x); el = atan2(u_z, |u_xy|) (equal to asin(u_z) on the unit sphere).
  jacobian << -u.y() / horizontal2, u.x() / horizontal2, 0.0,  //
      -u.x() * u.z() / horizontal, -u.y() * u.z() / horizontal, horizontal;
  return jacobian * covariance * jacobian.transpose();
}

namespace {
// Inverse of the leading dimensions x dimensions block (fixed sizes: no allocation per solve);
// false when that block is rank deficient.
template <int N>
bool invert_fixed(const Eigen::Matrix3d& matrix, Eigen::Matrix3d& inverse) {
  Eigen::FullPivLU<Eigen::Matrix<double, N, N>> lu(N, N);
  // Eigen's default rank threshold, set explicitly (GCC cannot see it is otherwise unused).
  lu.setThreshold(Eigen::NumTraits<double>::epsilon() * N);
  lu.compute(matrix.topLeftCorner<N, N>());
  if (lu.rank() < N) return false;
  inverse.topLeftCorner<N, N>() = lu.inverse();
  return true;
}

bool invert_leading_block(const Eigen::Matrix3d& matrix, int dimensions, Eigen::Matrix3d& inverse) {
  switch (dimensions) {
    case 1:
      return invert_fixed<1>(matrix, inverse);
    case 2:
      return invert_fixed<2>(matrix, inverse);
    case 3:
      return invert_fixed<3>(matrix, inverse);
    default:
      return false;
  }
}
}  // namespace

LsDoaSolver::LsDoaSolver(const ArrayGeometry& geometry, const LsDoaSettings& settings)
    : settings_(settings), array_to_site_(geometry.array_to_site()) {
  if (!(settings.speed_of_sound_mps > 0.0))
    throw std::invalid_argument("speed_of_sound_mps must be > 0");
  const int mics = static_cast<int>(geometry.mic_count());
  if (mics < 2) throw std::invalid_argument("array " + geometry.id + ": needs at least 2 mics");
  if (mics * (mics - 1) / 2 > kMaxPairs)
    throw std::invalid_argument("array " + geometry.id + ": at most 8 mics are supported");
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (int i = 0; i < mics; ++i) {
    for (int j = i + 1; j < mics; ++j) {
      const Eigen::Vector3d delta = (geometry.mics_m[static_cast<std::size_t>(i)] -
                                     geometry.mics_m[static_cast<std::size_t>(j)]) /
                                    settings.speed_of_sound_mps;
      if (!(delta.norm() > 0.0))
        throw std::invalid_argument("array " + geometry.id + ": mics " + std::to_string(i) +
                                    " and " + std::to_string(j) + " are at the same position");
      pair_vectors_.push_back(delta);
      pair_mics_.emplace_back(i, j);
      max_lags_s_.push_back(delta.norm());
      scatter += delta * delta.transpose();
    }
  }
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& mic : geometry.mics_m) centroid += mic;
  centroid /= mics;
  for (const Eigen::Vector3d& mic : geometry.mics_m) mics_centred_m_.push_back(mic - centroid);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  rank_ = rank_of_scatter(eigen.eigenvalues());
  for (int axis = 0; axis < 3; ++axis) subspace_.col(axis) = eigen.eigenvectors().col(2 - axis);
  if (rank_ == 1) {
    // The published cone axis points from mic 0 towards mic 1 (eigenvectors have no sign), and
    // the longest pair measures the finest angle.
    if ((geometry.mics_m[1] - geometry.mics_m[0]).dot(subspace_.col(0)) < 0.0)
      subspace_.col(0) = -subspace_.col(0);
    for (int p = 1; p < pair_count(); ++p)
      if (max_lags_s_[static_cast<std::size_t>(p)] >
          max_lags_s_[static_cast<std::size_t>(cone_pair_)])
        cone_pair_ = p;
  }
  const double position_std_s = geometry.mic_position_std_m / settings.speed_of_sound_mps;
  position_variance_s2_ = 2.0 * position_std_s * position_std_s;
}

DoaAmbiguity LsDoaSolver::ambiguity() const {
  if (rank_ >= 3) return DoaAmbiguity::none;
  return rank_ == 2 ? DoaAmbiguity::mirror_up_down : DoaAmbiguity::cone;
}

double LsDoaSolver::cone_cosine_for_tdoa(int pair, double tdoa_s) const {
  // tau_ij = -dp_ij . u, and dp_ij lies along the axis a: a . u = -tau / (dp_ij . a).
  return -tdoa_s / pair_vectors_[static_cast<std::size_t>(pair)].dot(subspace_.col(0));
}

double cone_angle_variance_rad2(double measured_cosine, double cosine_variance) {
  if (!(cosine_variance > 0.0) || !std::isfinite(cosine_variance) ||
      !std::isfinite(measured_cosine))
    return 0.0;
  // Directions uniform on the sphere make cos(theta) uniform on [-1, 1], so given the measured
  // cosine c^ the true one is a normal N(c^, s^2) truncated to [-1, 1], whose mode is the
  // reported clamp(c^). The variance published is that posterior's mean squared distance of
  // theta from the reported angle: calibrated by construction, the linearised s^2 / sin^2(theta)
  // away from the axis, and on it (c^ = 1: 1 - c = s |z|, theta ~ sqrt(2 s |z|)) E[theta^2] =
  // 2 s E|z| = 2 sqrt(2 / pi) s; a c^ beyond 1 says the source is nearer the axis still. The
  // integral runs over theta (c = cos theta, dc = sin theta dtheta), where the integrand is
  // smooth even at the axis.
  const double sigma = std::sqrt(cosine_variance);
  const double nearest = std::clamp(measured_cosine, -1.0, 1.0);
  const double reported_rad = std::acos(nearest);
  constexpr double kSpan = 8.0;  // standard deviations of the cosine each side
  const double low = std::max(-1.0, nearest - kSpan * sigma);
  const double high = std::min(1.0, nearest + kSpan * sigma);
  const double first = std::acos(high);
  const double last = std::acos(low);
  constexpr int kIntervals = 96;  // even (Simpson)
  const double step = (last - first) / kIntervals;
  // A cosine noise below the doubles' resolution of the angle: the first-order answer.
  if (!(step > 0.0)) return cosine_variance / std::max(1.0 - nearest * nearest, 1e-300);
  double mass = 0.0;
  double moment = 0.0;
  for (int i = 0; i <= kIntervals; ++i) {
    const double theta = first + step * i;
    const double z = (std::cos(theta) - measured_cosine) / sigma;
    const double simpson = i == 0 || i == kIntervals ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    const double density = simpson * std::exp(-0.5 * z * z) * std::sin(theta);
    mass += density;
    moment += density * (theta - reported_rad) * (theta - reported_rad);
  }
  return mass > 0.0 ? moment / mass : 0.0;
}

double LsDoaSolver::tdoa_for_direction(int pair, const Eigen::Vector3d& direction_array) const {
  return -pair_vectors_[static_cast<std::size_t>(pair)].dot(direction_array);
}

double LsDoaSolver::pair_variance(const PairTdoa& tdoa) const {
  if (!(tdoa.variance_s2 > 0.0) || !std::isfinite(tdoa.variance_s2) || !std::isfinite(tdoa.tdoa_s))
    return 0.0;
  return tdoa.variance_s2 + position_variance_s2_ +
         settings_.timing_floor_s * settings_.timing_floor_s;
}

LsDoaSolver::Arrival LsDoaSolver::arrival(const Eigen::Vector3d& u, double kappa, int mic) const {
  // (|r u - m| - r) / c with r = 1 / kappa. With D = sqrt(1 - 2 kappa a + kappa^2 |m|^2),
  // a = u.m: (D - 1) / kappa = (kappa |m|^2 - 2 a) / (D + 1), exact and smooth through
  // kappa = 0 (the plane wave, -a / c).
  const Eigen::Vector3d& position = mics_centred_m_[static_cast<std::size_t>(mic)];
  const double along = u.dot(position);
  const double squared = position.squaredNorm();
  const double root =
      std::sqrt(std::max(1e-12, 1.0 - 2.0 * kappa * along + kappa * kappa * squared));
  const double numerator = kappa * squared - 2.0 * along;
  const double denominator = (root + 1.0) * settings_.speed_of_sound_mps;
  const double root_by_kappa = (kappa * squared - along) / root;
  return {numerator / denominator, -1.0 / (root * settings_.speed_of_sound_mps),
          (squared * (root + 1.0) - numerator * root_by_kappa) / (denominator * (root + 1.0))};
}

bool LsDoaSolver::refine_near_field(std::span<const PairTdoa> tdoas, int skip_pair,
                                    Eigen::Vector3d& direction_array, Eigen::Matrix3d& covariance,
                                    double& chi2) const {
  const double kappa_std = settings_.near_field_kappa_std_per_m;
  const std::size_t count = std::min(pair_vectors_.size(), tdoas.size());
  const int mics = static_cast<int>(mics_centred_m_.size());
  // Pair weights once (0: not used), then every iteration reuses them.
  std::array<double, kMaxPairs> inverse_variance{};
  for (std::size_t p = 0; p < count; ++p) {
    const double variance = static_cast<int>(p) == skip_pair ? 0.0 : pair_variance(tdoas[p]);
    inverse_variance[p] = variance > 0.0 ? 1.0 / variance : 0.0;
  }
  Eigen::Vector3d u = direction_array;
  double kappa = 0.0;
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();
  Eigen::Vector3d tangent_1;
  Eigen::Vector3d tangent_2;
  std::array<Arrival, kMaxMics> arrivals{};
  std::array<double, kMaxMics> along_1{};  // d arrival / d alpha (first tangent), per mic
  std::array<double, kMaxMics> along_2{};
  for (int iteration = 0; iteration < 4; ++iteration) {
    // Tangent basis at u; parameters (alpha, beta, kappa) with u(alpha, beta) on the sphere.
    tangent_1 = u.unitOrthogonal();
    tangent_2 = u.cross(tangent_1);
    for (int m = 0; m < mics; ++m) {
      const auto at = static_cast<std::size_t>(m);
      arrivals[at] = arrival(u, kappa, m);
      along_1[at] = arrivals[at].d_along * tangent_1.dot(mics_centred_m_[at]);
      along_2[at] = arrivals[at].d_along * tangent_2.dot(mics_centred_m_[at]);
    }
    information = Eigen::Matrix3d::Zero();
    Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
    information(2, 2) = 1.0 / (kappa_std * kappa_std);
    gradient(2) = kappa / (kappa_std * kappa_std);
    for (std::size_t p = 0; p < count; ++p) {
      if (!(inverse_variance[p] > 0.0)) continue;
      const auto i = static_cast<std::size_t>(pair_mics_[p].first);
      const auto j = static_cast<std::size_t>(pair_mics_[p].second);
      const Eigen::Vector3d row(along_1[i] - along_1[j], along_2[i] - along_2[j],
                                arrivals[i].d_kappa - arrivals[j].d_kappa);
      const double residual = arrivals[i].time_s - arrivals[j].time_s - tdoas[p].tdoa_s;
      information += row * row.transpose() * inverse_variance[p];
      gradient += row * residual * inverse_variance[p];
    }
    const Eigen::Vector3d step = -information.ldlt().solve(gradient);
    if (!step.allFinite()) return false;
    u = (u + step(0) * tangent_1 + step(1) * tangent_2).normalized();
    kappa += step(2);
    if (step.head<2>().norm() < 1e-10) break;
  }
  // A curvature far beyond its prior is the fit bending lobes of different sources together,
  // not a close source: keep the plane wave (and let its residual judge it).
  if (!(std::abs(kappa) <= 3.0 * kappa_std)) return false;
  const Eigen::Matrix3d parameter_covariance = information.inverse();
  Eigen::Matrix<double, 3, 2> tangent;
  tangent << tangent_1, tangent_2;
  covariance = tangent * parameter_covariance.topLeftCorner<2, 2>() * tangent.transpose();
  if (!covariance.allFinite()) return false;
  direction_array = u;
  chi2 = (kappa / kappa_std) * (kappa / kappa_std);
  for (int m = 0; m < mics; ++m) arrivals[static_cast<std::size_t>(m)] = arrival(u, kappa, m);
  for (std::size_t p = 0; p < count; ++p) {
    if (!(inverse_variance[p] > 0.0)) continue;
    const double residual = arrivals[static_cast<std::size_t>(pair_mics_[p].first)].time_s -
                            arrivals[static_cast<std::size_t>(pair_mics_[p].second)].time_s -
                            tdoas[p].tdoa_s;
    chi2 += residual * residual * inverse_variance[p];
  }
  return true;
}

DoaSolution LsDoaSolver::solve(std::span<const PairTdoa> tdoas) const {
  return solve(tdoas, array_to_site_);
}

DoaSolution LsDoaSolver::solve(std::span<const PairTdoa> tdoas,
                               const Eigen::Matrix3d& array_to_site) const {
  ArrayFit best = solve_once(tdoas, -1);
  if (best.solution.accepted) return to_site(best, array_to_site);
  int usable = 0;
  for (std::size_t p = 0; p < pair_vectors_.size() && p < tdoas.size(); ++p)
    usable += pair_variance(tdoas[p]) > 0.0 ? 1 : 0;
  // Leaving one out must still over-determine the fit.
  if (usable < rank_ + 2) return to_site(best, array_to_site);
  for (int skip = 0; skip < pair_count(); ++skip) {
    if (pair_variance(tdoas[static_cast<std::size_t>(skip)]) <= 0.0) continue;
    ArrayFit candidate = solve_once(tdoas, skip);
    if (candidate.solution.accepted &&
        (!best.solution.accepted || candidate.solution.chi2_per_dof < best.solution.chi2_per_dof))
      best = candidate;
  }
  return to_site(best, array_to_site);
}

LsDoaSolver::ArrayFit LsDoaSolver::solve_once(std::span<const PairTdoa> tdoas,
                                              int skip_pair) const {
  ArrayFit fit;
  DoaSolution& solution = fit.solution;
  solution.ambiguity = ambiguity();
  solution.dropped_pair = skip_pair;
  const int dimensions = rank_;
  const Eigen::Matrix3d& basis = subspace_;
  // Normal equations in the geometry's own subspace (coordinates q = basis^T dp).
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  double peak_sum = 0.0;
  int used = 0;
  const std::size_t count = std::min(pair_vectors_.size(), tdoas.size());
  for (std::size_t p = 0; p < count; ++p) {
    if (static_cast<int>(p) == skip_pair) continue;
    const double variance = pair_variance(tdoas[p]);
    if (variance <= 0.0) continue;
    const double weight = 1.0 / variance;
    Eigen::Vector3d q = basis.transpose() * pair_vectors_[p];
    for (int axis = dimensions; axis < 3; ++axis) q(axis) = 0.0;
    normal += weight * q * q.transpose();
    rhs += weight * tdoas[p].tdoa_s * q;
    peak_sum += std::clamp(tdoas[p].peak_value, 0.0, 1.0);
    ++used;
  }
  solution.pairs_used = used;
  if (used < dimensions) return fit;
  Eigen::Matrix3d inverse = Eigen::Matrix3d::Zero();
  if (!invert_leading_block(normal, dimensions, inverse)) return fit;
  const Eigen::Vector3d v = -inverse * rhs;  // subspace coordinates
  const double norm = v.norm();
  solution.norm = norm;
  if (!std::isfinite(norm) || norm <= 0.0) return fit;

  Eigen::Vector3d direction_array;
  Eigen::Matrix3d direction_covariance = Eigen::Matrix3d::Zero();  // before the chi^2 inflation
  double near_field_chi2 = -1.0;  // set when the spherical-wavefront fit was used
  if (dimensions == 3) {
    if (std::abs(norm - 1.0) > settings_.max_norm_error) return fit;
    const Eigen::Vector3d u = v / norm;
    direction_array = basis * u;
    const Eigen::Matrix3d tangent = Eigen::Matrix3d::Identity() - u * u.transpose();
    direction_covariance =
        basis * (tangent * inverse * tangent) * basis.transpose() / (norm * norm);
    if (settings_.near_field_kappa_std_per_m > 0.0) {
      Eigen::Vector3d refined = direction_array;
      Eigen::Matrix3d refined_covariance;
      if (refine_near_field(tdoas, skip_pair, refined, refined_covariance, near_field_chi2)) {
        direction_array = refined;
        direction_covariance = refined_covariance;
      }
    }
  } else if (dimensions == 2) {
    if (norm > 1.0 + settings_.max_norm_error) return fit;
    const Eigen::Vector2d in_plane = v.head<2>() / std::max(norm, 1.0);
    const double height = std::sqrt(std::max(0.0, 1.0 - in_plane.squaredNorm()));
    // The image on the +normal side; to_site() mirrors it when that side is down.
    const Eigen::Vector3d normal_axis = basis.col(2);
    direction_array = basis.leftCols<2>() * in_plane + normal_axis * height;
    Eigen::Matrix<double, 3, 2> jacobian =
        basis.leftCols<2>() - normal_axis * in_plane.transpose() / std::max(height, kMinLever);
    direction_covariance = jacobian * inverse.topLeftCorner<2, 2>() * jacobian.transpose();
  } else {
    if (norm > 1.0 + settings_.max_norm_error) return fit;
    fit.cone_cosine = v(0);
    // The residual at the cosine clamped to the cone's edge: a cosine a few sigma beyond +-1 is a
    // source near the axis plus noise, one far beyond is no plane wave (the gate below).
    direction_array = basis.col(0) * std::clamp(v(0), -1.0, 1.0);
  }
  if (dimensions >= 2) direction_array.normalize();

  double chi2 = 0.0;
  for (std::size_t p = 0; p < count && near_field_chi2 < 0.0; ++p) {
    if (static_cast<int>(p) == skip_pair) continue;
    const double variance = pair_variance(tdoas[p]);
    if (variance <= 0.0) continue;
    const double residual = tdoas[p].tdoa_s + pair_vectors_[p].dot(direction_array);
    chi2 += residual * residual / variance;
  }
  if (near_field_chi2 >= 0.0) chi2 = near_field_chi2;
  const int dof = std::max(1, used - dimensions);
  solution.chi2_per_dof = chi2 / dof;
  if (!(solution.chi2_per_dof <= settings_.max_chi2_per_dof)) return fit;
  // An honest covariance: when the residual says the TDOA noise was larger than modelled, the
  // direction is that much less certain.
  const double inflation = std::max(1.0, solution.chi2_per_dof);
  if (dimensions == 1) {
    // The cosine's variance is inflated by the fit's own misfit only (chi^2 is quadratic in the
    // cosine: the clamp adds (clamp - c^)^2 / var): the posterior already reads the overshoot.
    const double excess = std::clamp(fit.cone_cosine, -1.0, 1.0) - fit.cone_cosine;
    const double fit_chi2 = std::max(0.0, chi2 - excess * excess / inverse(0, 0));
    fit.cone_angle_rad = std::acos(std::clamp(fit.cone_cosine, -1.0, 1.0));
    fit.cone_angle_variance_rad2 =
        cone_angle_variance_rad2(fit.cone_cosine, inverse(0, 0) * std::max(1.0, fit_chi2 / dof));
  } else {
    fit.direction = direction_array;
    fit.covariance = direction_covariance * inflation;
  }
  const double peak_mean = used > 0 ? peak_sum / used : 0.0;
  solution.quality = std::clamp(peak_mean * std::exp(-std::max(0.0, solution.chi2_per_dof - 1.0) /
                                                     settings_.max_chi2_per_dof),
                                0.0, 1.0);
  solution.accepted = true;
  return fit;
}

DoaSolution LsDoaSolver::to_site(const ArrayFit& fit, const Eigen::Matrix3d& array_to_site) const {
  DoaSolution solution = fit.solution;
  if (!solution.accepted) return solution;
  Eigen::Vector3d direction = array_to_site * fit.direction;
  Eigen::Matrix3d covariance = array_to_site * fit.covariance * array_to_site.transpose();
  if (rank_ == 2) {
    // Report the image above the array plane (as seen in the site frame).
    Eigen::Vector3d normal = array_to_site * subspace_.col(2);
    if (normal.z() < 0.0) {
      const Eigen::Matrix3d mirror =
          Eigen::Matrix3d::Identity() - 2.0 * normal * normal.transpose();
      direction = mirror * direction;
      covariance = mirror * covariance * mirror;
      normal = -normal;
    }
    solution.ambiguity_axis_site = normal;
  } else if (rank_ == 1) {
    // The cone's display point: the horizontal one (or, for a vertical axis, the one towards
    // site +x). Only the angle to the axis is measured; the angle around it gets a variance
    // that says so.
    const Eigen::Vector3d axis = array_to_site * subspace_.col(0);
    Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(axis);
    if (across.norm() < 1e-9) across = Eigen::Vector3d::UnitX();
    across.normalize();
    const double cosine = std::cos(fit.cone_angle_rad);
    const double sine = std::sin(fit.cone_angle_rad);
    direction = axis * cosine + across * sine;
    const Eigen::Vector3d along_cone = -axis * sine + across * cosine;
    const Eigen::Vector3d around_axis = direction.cross(along_cone).normalized();
    covariance = along_cone * along_cone.transpose() * fit.cone_angle_variance_rad2 +
                 around_axis * around_axis.transpose() * kUnresolvedVariance;
    solution.ambiguity_axis_site = axis;
    solution.cone_angle_rad = fit.cone_angle_rad;
    solution.cone_angle_variance_rad2 = fit.cone_angle_variance_rad2;
  }
  solution.direction_site = direction.normalized();
  solution.azel_covariance_rad2 =
      azel_covariance_from_direction(solution.direction_site, covariance);
  return solution;
}

}  // namespace dronetrack::doa
