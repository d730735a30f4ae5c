// A track whose range one array alone held (a one-array track, or an open range along the ray
// of the one array still hearing it) handed to the default filter once a second array fixes it.
#include <array>

#include <Eigen/Cholesky>

#include "fusion/fusion_engine_impl.hpp"
#include "fusion/gaussian_sum_filter.hpp"

namespace dronetrack::fusion {

void log_branches(Track& track, double time_s) {
  const auto* sum = dynamic_cast<const GaussianSumFilter*>(track.filter.get());
  if (sum == nullptr) return;
  int left = 0;
  for (int branch = 0; branch < 4; ++branch) left += sum->branch_weight(branch) > 0.0 ? 1 : 0;
  if (left == track.branches_left) return;
  const StateVector& x = sum->mean();
  log::debug("fusion: track ", track.id, " t ", time_s, " s: ", left, " branch(es) left",
             track.branches_left < 0 ? " at its first update, " : ", ", sum->hypothesis_count(),
             " hypotheses, mean (", x(0), ", ", x(1), ", ", x(2), ")");
  track.branches_left = left;
}

bool FusionEngine::Impl::refix_by_triangulation(Track& track, int origin_array,
                                                const MeasurementCovariance& origin_noise,
                                                const doa::DoaMeasurement& m,
                                                const DoaMeasurementModel& model, double time_s) {
  if (model.kind != MeasurementKind::azel) return false;  // a cone or a mirror pair: no one ray
  const Eigen::Vector3d origin = last_centre_m[static_cast<std::size_t>(origin_array)];
  const Eigen::Vector3d along = position_of(track.filter->mean()) - origin;
  if (!(along.norm() > 1.0)) return false;
  // The mixture's mean lies on the bearing (its hypotheses spread along it, not across).
  const std::array<Ray, 2> pair{Ray{origin, along.normalized(), origin_noise},
                                Ray{model.centre_m, m.direction, noise_of(m)}};
  const auto fix = triangulate(pair, params.triangulation);
  if (!fix || !fix->in_front || below_ground(*fix)) return false;
  // The rays must meet (two rays, three unknowns: one dof left), where the track says the source
  // may be: a DOA of another source that the wide mixture happened to gate is no hand-over.
  if (fix->chi_square > chi_square_quantile(params.gate_probability, 1)) return false;
  const Eigen::Vector3d offset = fix->position_m - position_of(track.filter->mean());
  const Eigen::Matrix3d spread =
      track.filter->covariance().topLeftCorner<3, 3>() + fix->covariance_m2;
  if (offset.dot(spread.ldlt().solve(offset)) > chi_square_quantile(params.gate_probability, 3))
    return false;
  StateVector mean;
  StateCovariance covariance;
  state_from_fix(*fix, model.centre_m, model.speed_of_sound_mps, mean, covariance);
  FilterSettings settings = filter_settings;
  settings.random_seed = static_cast<std::uint64_t>(track.id);
  auto filter = make_track_filter(params.filter, settings);
  filter->initialise(mean, covariance);
  track.filter = std::move(filter);
  track.time_s = time_s;
  track.one_array = false;
  return true;
}

void FusionEngine::Impl::hand_over(Track& track) {
  // Only a narrow Gaussian: a wide one (hypotheses merged while the range diffused) would be
  // linearised far from the truth by the next bearing.
  const double max_variance = params.max_position_std_m * params.max_position_std_m;
  if (track.filter->hypothesis_count() != 1 || recent_arrays(track, arrays.size()) < 2 ||
      !(track.filter->covariance().diagonal().segment<3>(StateBlock::position).maxCoeff() <=
        max_variance))
    return;
  // A second array now resolves the range: the default filter (and motion model) takes the
  // collapsed Gaussian.
  FilterSettings settings = filter_settings;
  settings.random_seed = static_cast<std::uint64_t>(track.id);
  auto filter = make_track_filter(params.filter, settings);
  filter->initialise(track.filter->mean(), track.filter->covariance());
  track.filter = std::move(filter);
  track.one_array = false;
}

}  // namespace dronetrack::fusion
