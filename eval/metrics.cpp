#include "eval/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <set>

#include "config/config_reader.hpp"
#include "doa/array_geometry.hpp"
#include "eval/readers.hpp"
#include "fusion/assignment.hpp"

namespace dronetrack::eval {
namespace {

// Index i with time_s[i] <= t < time_s[i+1] and the fraction of the way to i+1.
std::pair<std::size_t, double> locate(const std::vector<double>& time_s, double t) {
  if (time_s.size() < 2 || t <= time_s.front()) return {0, 0.0};
  if (t >= time_s.back()) return {time_s.size() - 2, 1.0};
  const auto upper = std::upper_bound(time_s.begin(), time_s.end(), t);
  const auto i = static_cast<std::size_t>(upper - time_s.begin()) - 1;
  const double span = time_s[i + 1] - time_s[i];
  return {i, span > 0.0 ? (t - time_s[i]) / span : 0.0};
}

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(std::lround(q * static_cast<double>(values.size() - 1)));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

struct ErrorSamples {
  std::vector<double> error_m;
  double sum2_3d = 0.0;
  double sum2_horizontal = 0.0;
  double sum2_vertical = 0.0;
  double pfe_total_sum = 0.0;
  int pfe_total_count = 0;
  Eigen::Vector3d pfe_axis_sum = Eigen::Vector3d::Zero();
  Eigen::Vector3i pfe_axis_count = Eigen::Vector3i::Zero();

  void add(const Eigen::Vector3d& truth, const Eigen::Vector3d& estimate,
           const Eigen::Vector3d& centroid) {
    const Eigen::Vector3d error = estimate - truth;
    error_m.push_back(error.norm());
    sum2_3d += error.squaredNorm();
    sum2_horizontal += error.head<2>().squaredNorm();
    sum2_vertical += error.z() * error.z();
    const Eigen::Vector3d relative = truth - centroid;
    // Samples where the reference is (almost) zero would divide by nothing; the seed's per-axis
    // figures are dominated by such samples, which is why the total is the one to compare.
    if (relative.norm() > 1e-6) {
      pfe_total_sum += error.norm() / relative.norm();
      ++pfe_total_count;
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (std::abs(relative(axis)) > 1e-6) {
        pfe_axis_sum(axis) += std::abs(error(axis)) / std::abs(relative(axis));
        ++pfe_axis_count(axis);
      }
    }
  }

  PositionMetrics summarise() const {
    PositionMetrics metrics;
    metrics.samples = static_cast<int>(error_m.size());
    if (error_m.empty()) return metrics;
    const double n = static_cast<double>(error_m.size());
    metrics.rmse_3d_m = std::sqrt(sum2_3d / n);
    metrics.rmse_horizontal_m = std::sqrt(sum2_horizontal / n);
    metrics.rmse_vertical_m = std::sqrt(sum2_vertical / n);
    metrics.median_error_m = quantile(error_m, 0.5);
    metrics.p90_error_m = quantile(error_m, 0.9);
    metrics.max_error_m = *std::max_element(error_m.begin(), error_m.end());
    metrics.pfe_total_percent = pfe_total_count ? 100.0 * pfe_total_sum / pfe_total_count : 0.0;
    for (int axis = 0; axis < 3; ++axis) {
      metrics.pfe_axis_percent(axis) =
          pfe_axis_count(axis) ? 100.0 * pfe_axis_sum(axis) / pfe_axis_count(axis) : 0.0;
    }
    return metrics;
  }
};

// The other truth source nearest to `position` within max(gate, 5 % of its distance from the
// array centroid), or -1.
int nearest_other(const Truth& truth, const Eigen::Vector3d& position, double t, double gate_m,
                  const Eigen::Vector3d& centroid) {
  int best = -1;
  double best_distance = std::numeric_limits<double>::infinity();
  for (std::size_t o = 0; o < truth.others.size(); ++o) {
    const TruthSource& other = truth.others[o];
    if (!other.alive_at(t)) continue;
    const Eigen::Vector3d where = other.position_at(t);
    const double distance = (position - where).norm();
    const double gate = std::max(gate_m, 0.05 * (where - centroid).norm());
    if (distance <= gate && distance < best_distance) {
      best = static_cast<int>(o);
      best_distance = distance;
    }
  }
  return best;
}

// Length of the truth's path between two times (its samples inside, plus the end points).
double path_length(const TruthSource& source, double from_s, double to_s) {
  if (!(to_s > from_s) || source.time_s.empty()) return 0.0;
  double length = 0.0;
  Eigen::Vector3d previous = source.position_at(from_s);
  for (std::size_t i = 0; i < source.time_s.size(); ++i) {
    if (source.time_s[i] <= from_s || source.time_s[i] >= to_s) continue;
    length += (source.position_m[i] - previous).norm();
    previous = source.position_m[i];
  }
  return length + (source.position_at(to_s) - previous).norm();
}

// A cone DOA's error is the error of the one angle it measured; any other's, the angle between
// the directions.
double doa_error_deg(const DoaRecord& doa, const Eigen::Vector3d& truth_direction) {
  if (doa.cone) {
    const double truth_angle_deg =
        std::acos(std::clamp(doa.cone->axis.dot(truth_direction), -1.0, 1.0)) * 180.0 /
        std::numbers::pi;
    return std::abs(truth_angle_deg - doa.cone->angle_deg);
  }
  if (doa.mirror_normal) {
    const Eigen::Vector3d& n = *doa.mirror_normal;
    const Eigen::Vector3d mirrored = truth_direction - 2.0 * truth_direction.dot(n) * n;
    return std::min(doa::angle_between_deg(truth_direction, doa.direction.normalized()),
                    doa::angle_between_deg(mirrored, doa.direction.normalized()));
  }
  return doa::angle_between_deg(truth_direction, doa.direction.normalized());
}

// sqrt of the chi-square 99 % quantile with 3 degrees of freedom (11.345).
constexpr double kNinetyNinePercent3d = 3.3682;

// Whether a one-array track follows a truth position in the sense of EvalOptions: on the
// source's bearing from some array, and the source within its stated extent.
bool one_array_follows(const TrackRecord& track, const Eigen::Vector3d& truth_position,
                       const Truth& truth, const EvalOptions& options) {
  if (!track.one_array || !(track.position_std_m.minCoeff() > 0.0)) return false;
  const Eigen::Vector3d error = track.position_m - truth_position;
  if (error.cwiseQuotient(track.position_std_m).norm() > kNinetyNinePercent3d) return false;
  for (const auto& [id, centre] : truth.array_centres_m) {
    const Eigen::Vector3d to_track = track.position_m - centre;
    const Eigen::Vector3d to_truth = truth_position - centre;
    if (to_track.norm() > 0.0 && to_truth.norm() > 0.0 &&
        doa::angle_between_deg(to_track, to_truth) <= options.one_array_bearing_gate_deg)
      return true;
  }
  return false;
}

bool counted(const TrackRecord& track, const EvalOptions& options) {
  return track.status != "tentative" || options.include_tentative;
}

}  // namespace

Eigen::Vector3d TruthSource::position_at(double t) const {
  if (position_m.empty()) return Eigen::Vector3d::Zero();
  if (position_m.size() == 1) return position_m.front();
  const auto [i, fraction] = locate(time_s, t);
  return position_m[i] + fraction * (position_m[i + 1] - position_m[i]);
}

std::optional<Eigen::Vector3d> TruthSource::direction_at(const std::string& array, double t) const {
  const auto found = direction_by_array.find(array);
  if (found == direction_by_array.end() || found->second.empty()) return std::nullopt;
  const auto& directions = found->second;
  if (directions.size() == 1) return directions.front().normalized();
  const auto [i, fraction] = locate(time_s, t);
  const Eigen::Vector3d blend = directions[i] + fraction * (directions[i + 1] - directions[i]);
  if (!(blend.norm() > 0.0)) return std::nullopt;
  return blend.normalized();
}

std::vector<DoaArrayMetrics> doa_errors(const Truth& truth, const std::vector<DoaRecord>& doas,
                                        int* unmatched) {
  std::map<std::string, std::vector<double>> errors;
  std::map<std::string, std::vector<double>> times;
  int missing = 0;
  for (const DoaRecord& doa : doas) {
    double best = std::numeric_limits<double>::infinity();
    for (const TruthSource& source : truth.sources) {
      if (!source.alive_at(doa.time_s)) continue;
      const auto direction = source.direction_at(doa.array, doa.time_s);
      if (!direction) continue;
      best = std::min(best, doa_error_deg(doa, *direction));
    }
    if (std::isfinite(best)) {
      errors[doa.array].push_back(best);
      times[doa.array].push_back(doa.time_s);
    } else {
      ++missing;
    }
  }
  if (unmatched != nullptr) *unmatched = missing;
  std::vector<DoaArrayMetrics> out;
  for (const auto& [array, values] : errors) {
    DoaArrayMetrics metrics;
    metrics.array = array;
    metrics.count = static_cast<int>(values.size());
    metrics.median_error_deg = quantile(values, 0.5);
    metrics.p90_error_deg = quantile(values, 0.9);
    double sum = 0.0;
    for (double v : values) sum += v;
    metrics.mean_error_deg = sum / static_cast<double>(values.size());
    metrics.time_s = std::move(times[array]);
    metrics.error_deg = values;
    out.push_back(metrics);
  }
  return out;
}

EvalReport evaluate(const Truth& truth, const std::vector<TrackRecord>& tracks,
                    const std::vector<DoaRecord>& doas, const EvalOptions& options,
                    const std::vector<AlertRecord>* alerts) {
  EvalReport report;
  for (std::size_t o = 0; o < truth.others.size(); ++o)
    report.others.push_back({truth.others[o].id, truth.other_classes[o], 0.0, 0.0});
  // (track id, tick index) -> follows a drone, for the alerts.
  std::map<std::pair<int, long>, bool> follows_drone;
  report.options = options;
  if (!truth.array_centres_m.empty()) {
    for (const auto& [id, centre] : truth.array_centres_m) report.array_centroid_m += centre;
    report.array_centroid_m /= static_cast<double>(truth.array_centres_m.size());
  }

  // Track lines grouped by output time.
  std::map<double, std::vector<const TrackRecord*>> by_time;
  for (const TrackRecord& track : tracks) by_time[track.time_s].push_back(&track);
  double tick = options.tick_s;
  if (!(tick > 0.0)) {
    std::vector<double> steps;
    double previous = std::numeric_limits<double>::quiet_NaN();
    for (const auto& [t, lines] : by_time) {
      if (std::isfinite(previous)) steps.push_back(t - previous);
      previous = t;
    }
    tick = steps.empty() ? 0.1 : quantile(steps, 0.5);
  }
  report.tick_s = tick;

  double start = std::numeric_limits<double>::infinity();
  double end = -std::numeric_limits<double>::infinity();
  for (const TruthSource& source : truth.sources) {
    if (source.time_s.empty()) continue;
    start = std::min(start, source.time_s.front());
    end = std::max(end, source.time_s.back());
  }
  if (truth.recording_end_s) end = std::min(end, *truth.recording_end_s);
  start += options.skip_s;
  report.start_s = start;
  report.end_s = end;
  // Each step assigns tracks to sources: bound them before looping.
  if (std::isfinite(start) && end > start && (end - start) / tick > kMaxEvalSteps) {
    throw InputError("a step of " + config::format_number(tick) + " s over the truth's " +
                     config::format_number(end - start) + " s makes more than " +
                     config::format_number(kMaxEvalSteps) + " steps; use a larger --tick-s");
  }

  ErrorSamples all;
  std::vector<ErrorSamples> per_source(truth.sources.size());
  report.sources.resize(truth.sources.size());
  for (std::size_t s = 0; s < truth.sources.size(); ++s) report.sources[s].id = truth.sources[s].id;
  std::vector<int> last_track(truth.sources.size(), -1);
  // Start of the current run of ticks within the convergence gate (-1: none), per source.
  std::vector<double> within_gate_since(truth.sources.size(), -1.0);
  std::vector<double> first_alive(truth.sources.size(), -1.0);
  std::set<int> counted_ids;
  fusion::Assignment assignment;
  std::vector<double> cost;
  std::vector<int> track_to_source;
  std::vector<const TrackRecord*> live;
  std::vector<std::size_t> alive;

  const auto tick_count = std::isfinite(start) && end >= start
                              ? static_cast<long>(std::floor((end - start) / tick + 1e-9)) + 1
                              : 0L;
  for (long k = 0; k < tick_count; ++k) {
    const double t = start + static_cast<double>(k) * tick;
    live.clear();
    const auto nearest = by_time.lower_bound(t - 0.5 * tick);
    if (nearest != by_time.end() && nearest->first < t + 0.5 * tick) {
      for (const TrackRecord* track : nearest->second) {
        if (counted(*track, options)) live.push_back(track);
      }
    }
    alive.clear();
    for (std::size_t s = 0; s < truth.sources.size(); ++s) {
      if (truth.sources[s].alive_at(t)) alive.push_back(s);
    }
    const int rows = static_cast<int>(live.size());
    const int cols = static_cast<int>(alive.size());
    cost.assign(static_cast<std::size_t>(rows) * cols, fusion::kForbidden);
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const Eigen::Vector3d truth_position = truth.sources[alive[c]].position_at(live[r]->time_s);
        const double distance = (live[r]->position_m - truth_position).norm();
        if (distance <= options.association_gate_m ||
            one_array_follows(*live[r], truth_position, truth, options)) {
          cost[static_cast<std::size_t>(r) * cols + c] = distance;
        }
      }
    }
    assignment.solve(cost, rows, cols, track_to_source);
    std::vector<char> source_covered(truth.sources.size(), 0);
    for (int r = 0; r < rows; ++r) {
      counted_ids.insert(live[r]->id);
      report.track_time_s += tick;
      const bool says_drone = live[r]->track_class == "drone";
      follows_drone[{live[r]->id, k}] = track_to_source[r] >= 0;
      if (track_to_source[r] < 0) {
        report.false_track_time_s += tick;
        if (says_drone) report.non_drone_as_drone_time_s += tick;
        if (const int o = nearest_other(truth, live[r]->position_m, live[r]->time_s,
                                        options.association_gate_m, report.array_centroid_m);
            o >= 0) {
          report.others[static_cast<std::size_t>(o)].tracked_time_s += tick;
          if (says_drone) report.others[static_cast<std::size_t>(o)].as_drone_time_s += tick;
        } else {
          report.ghost_track_time_s += tick;
        }
        continue;
      }
      const std::size_t s = alive[track_to_source[r]];
      const TruthSource& source = truth.sources[s];
      const Eigen::Vector3d truth_position = source.position_at(live[r]->time_s);
      all.add(truth_position, live[r]->position_m, report.array_centroid_m);
      per_source[s].add(truth_position, live[r]->position_m, report.array_centroid_m);
      SourceMetrics& metrics = report.sources[s];
      metrics.tracked_time_s += tick;
      if (metrics.first_tracked_s < 0.0) metrics.first_tracked_s = t;
      if (says_drone) {
        metrics.drone_class_time_s += tick;
        if (metrics.classified_after_s < 0.0)
          metrics.classified_after_s = t - metrics.first_tracked_s;
      }
      if (last_track[s] >= 0 && last_track[s] != live[r]->id) ++metrics.id_switches;
      last_track[s] = live[r]->id;
      if (std::find(metrics.track_ids.begin(), metrics.track_ids.end(), live[r]->id) ==
          metrics.track_ids.end()) {
        metrics.track_ids.push_back(live[r]->id);
      }
      const double error_m = (live[r]->position_m - truth_position).norm();
      if (error_m <= options.coverage_gate_m ||
          one_array_follows(*live[r], truth_position, truth, options))
        source_covered[s] = 1;
      if (live[r]->one_array) metrics.one_array_time_s += tick;
      metrics.final_error_m = error_m;
      metrics.errors.push_back({live[r]->time_s, live[r]->id, error_m});
      if (error_m > options.converge_gate_m) {
        within_gate_since[s] = -1.0;
      } else if (within_gate_since[s] < 0.0) {
        within_gate_since[s] = t;
      }
    }
    for (std::size_t s : alive) {
      if (first_alive[s] < 0.0) first_alive[s] = t;
      report.sources[s].truth_time_s += tick;
      if (source_covered[s]) report.sources[s].covered_time_s += tick;
    }
  }

  double truth_time = 0.0;
  double covered_time = 0.0;
  for (std::size_t s = 0; s < truth.sources.size(); ++s) {
    SourceMetrics& metrics = report.sources[s];
    metrics.position = per_source[s].summarise();
    metrics.coverage =
        metrics.truth_time_s > 0.0 ? metrics.covered_time_s / metrics.truth_time_s : 0.0;
    truth_time += metrics.truth_time_s;
    covered_time += metrics.covered_time_s;
    metrics.drone_class_share =
        metrics.tracked_time_s > 0.0 ? metrics.drone_class_time_s / metrics.tracked_time_s : 0.0;
    report.id_switches += metrics.id_switches;
    if (within_gate_since[s] >= 0.0)
      metrics.converged_after_s = within_gate_since[s] - first_alive[s];
    metrics.travelled_m = path_length(truth.sources[s], start, end);
  }
  report.position = all.summarise();
  report.coverage = truth_time > 0.0 ? covered_time / truth_time : 0.0;
  report.tracks_seen = static_cast<int>(counted_ids.size());
  report.false_track_fraction =
      report.track_time_s > 0.0 ? report.false_track_time_s / report.track_time_s : 0.0;
  report.ghost_track_fraction =
      report.track_time_s > 0.0 ? report.ghost_track_time_s / report.track_time_s : 0.0;
  const double run_s = std::max(end - start, 0.0);
  report.non_drone_as_drone_fraction = run_s > 0.0 ? report.non_drone_as_drone_time_s / run_s : 0.0;
  if (alerts != nullptr) {
    report.alerts_read = static_cast<int>(alerts->size());
    for (const AlertRecord& alert : *alerts) {
      if (alert.event != "entered") continue;
      const long k = std::lround((alert.time_s - start) / tick);
      const auto found = follows_drone.find({alert.track_id, k});
      if (found != follows_drone.end() && found->second) {
        ++report.drone_zone_entries;
      } else {
        ++report.non_drone_zone_entries;
      }
    }
  }
  if (!doas.empty()) report.doa = doa_errors(truth, doas, &report.doa_unmatched);
  return report;
}

}  // namespace dronetrack::eval
