// Manoeuvre onset (issue 17): two consecutive DOAs of one array beyond a confirmed track's gate
// that agree with each other widen the track by a manoeuvre's process noise
// (fusion_engine_impl.hpp, kManoeuvreRunGapS).
#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "fusion/fusion_engine_impl.hpp"

namespace dronetrack::fusion {

int FusionEngine::Impl::follow_manoeuvre(Track& track, int array, std::size_t begin, int doa_count,
                                         double time_s) {
  const std::uint64_t bit = std::uint64_t{1} << array;
  int nearest = -1;
  double nearest_d2 = std::numeric_limits<double>::infinity();
  Measurement residual = Measurement::Zero();
  MeasurementCovariance covariance = MeasurementCovariance::Identity();
  for (int j = 0; j < doa_count; ++j) {
    const doa::DoaMeasurement& m = queue[begin + static_cast<std::size_t>(j)];
    // A DOA a tentative track took is no evidence against a manoeuvre: where the confirmed track
    // falls behind, a young track along the array's ray (an outlier pair's) gates it first.
    if (doa_confirmed[static_cast<std::size_t>(j)] != 0 || m.ambiguity != doa::DoaAmbiguity::none)
      continue;
    Innovation candidate = track.innovation;
    candidate.covariance += track.inflation * own_noise(m);
    const Measurement r = candidate.residual(measured(m));
    const double d2 = r.dot(candidate.covariance.ldlt().solve(r));
    if (d2 < nearest_d2) {
      nearest = j;
      nearest_d2 = d2;
      residual = r;
      covariance = candidate.covariance;
    }
  }
  // Within the gate yet untaken: refused by the filter, nothing to judge.
  if (nearest < 0 || nearest_d2 <= likelihood->gate_d2(2)) {
    track.unexplained_arrays &= ~bit;
    return -1;
  }
  // Within a manoeuvre's reach: the position spread it builds, seen from the array (an azimuth
  // step is 1 / cos(elevation) wider).
  const Eigen::Vector3d centre = frame_model.centre_m;
  const double range_m = std::max((position_of(track.filter->mean()) - centre).norm(), 1.0);
  const double reach_rad2 = manoeuvre_position_variance_m2 / (range_m * range_m);
  const double cos_elevation = std::max(std::cos(track.innovation.predicted(1)), 0.05);
  MeasurementCovariance reach = covariance;
  reach(0, 0) += reach_rad2 / (cos_elevation * cos_elevation);
  reach(1, 1) += reach_rad2;
  if (residual.dot(reach.ldlt().solve(residual)) > likelihood->gate_d2(2)) {
    track.unexplained_arrays &= ~bit;
    return -1;
  }
  const doa::DoaMeasurement& m = queue[begin + static_cast<std::size_t>(nearest)];
  const MeasurementCovariance noise = noise_of(m);
  const auto a = static_cast<std::size_t>(array);
  bool agrees = false;
  if ((track.unexplained_arrays & bit) != 0 &&
      time_s - track.unexplained_s[a] <= kManoeuvreRunGapS) {
    const Measurement step = residual - track.unexplained_residual[a];
    agrees =
        step.dot((noise + track.unexplained_noise[a]).ldlt().solve(step)) <= likelihood->gate_d2(2);
  }
  track.unexplained_arrays |= bit;
  track.unexplained_s[a] = time_s;
  track.unexplained_residual[a] = residual;
  track.unexplained_noise[a] = noise;
  if (!agrees || !track.filter->add_process_noise(manoeuvre_noise)) return -1;
  ++counters.manoeuvres_followed;
  track.unexplained_arrays &= ~bit;
  const FilterStatus status =
      track.filter->innovation(frame_model, floor_of(m, track.inflation), track.innovation);
  note(status);
  if (status == FilterStatus::failed) return -1;
  Innovation innovation = track.innovation;
  innovation.covariance += track.inflation * own_noise(m);
  innovation.noise = track.inflation * noise;
  const Measurement z = measured(m);
  if (innovation.mahalanobis2(z) > likelihood->gate_d2(2)) return -1;
  const FilterStatus update_status = track.filter->update(innovation, z);
  note(update_status);
  if (update_status == FilterStatus::failed) return -1;
  record_update(track, array, m.acoustic, time_s);
  return nearest;
}

}  // namespace dronetrack::fusion
