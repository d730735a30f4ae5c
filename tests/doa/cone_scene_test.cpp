// A two-mic pair in the simulator's scenes (issue 15): the cone angle the node publishes against
// the angle between the pair's axis and the true direction (spherical propagation, the
// simulator's rotor signal and noise), over a pass from one end of the axis to the other and
// for a drone hovering exactly at endfire; the published variance against the errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include <nlohmann/json.hpp>

#include "doa/node_pipeline.hpp"
#include "sim/render.hpp"
#include "sim/scenario.hpp"

namespace dronetrack::doa {
namespace {

using nlohmann::json;

constexpr double kYawDeg = 30.0;

json pair_scene(const json& trajectory, double duration_s, double reflection) {
  const json rotor = {{"type", "rotor"}, {"blade_pass_hz", 180},      {"rpm_wander", 0.025},
                      {"harmonics", 40}, {"slope_db_per_octave", -2}, {"broadband_db", -8}};
  return {{"seed", 9},
          {"sample_rate_hz", 48000},
          {"duration_s", duration_s},
          {"ground", {{"reflection_coefficient", reflection}}},
          {"site",
           {{"speed_of_sound_mps", 343.0},
            {"arrays",
             {{{"id", "P1"},
               {"position_m", {0.0, 0.0, 1.5}},
               {"yaw_deg", kYawDeg},
               {"mics_m", {{-0.3, 0.0, 0.0}, {0.3, 0.0, 0.0}}}}}}}},
          {"sources",
           {{{"id", "D1"},
             {"kind", "drone"},
             {"level_db", 90},
             {"signal", rotor},
             {"trajectory", trajectory}}}},
          {"noise", {{"sensor", {{"snr_db", 15}}}}}};
}

Eigen::Vector3d truth_direction(const sim::SourceTruth& source, double time_s) {
  const auto upper = std::upper_bound(source.t_s.begin(), source.t_s.end(), time_s);
  const auto index = std::clamp<std::size_t>(static_cast<std::size_t>(upper - source.t_s.begin()),
                                             1, source.t_s.size() - 1);
  const double fraction = std::clamp(
      (time_s - source.t_s[index - 1]) / (source.t_s[index] - source.t_s[index - 1]), 0.0, 1.0);
  return (source.direction[0][index - 1] * (1.0 - fraction) + source.direction[0][index] * fraction)
      .normalized();
}

struct SceneFigures {
  int doas = 0;
  double median_error_deg = 0.0;
  double p90_error_deg = 0.0;
  double mean_nees = 0.0;
  double min_truth_deg = 180.0;
  double max_truth_deg = 0.0;
};

SceneFigures run_scene(const json& document) {
  const sim::Scenario scenario = sim::parse_scenario(document, ".");
  const sim::RenderedArray audio = sim::render_array(scenario, 0);
  const sim::Truth truth = sim::compute_truth(scenario);
  const ArrayGeometry geometry = scenario.site.arrays[0].geometry;
  NodePipeline pipeline(geometry, 0, scenario.site.doa, audio.sample_rate_hz, 343.0);
  std::vector<DoaMeasurement> doas;
  const std::size_t block = 2048;
  for (std::size_t first = 0; first < audio.frames(); first += block) {
    const std::size_t count = std::min(block, audio.frames() - first);
    pipeline.process({static_cast<std::int64_t>(first), static_cast<int>(audio.channels), count,
                      audio.samples.data() + first * audio.channels},
                     doas);
  }
  const Eigen::Vector3d axis =
      Eigen::AngleAxisd(kYawDeg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()) *
      Eigen::Vector3d::UnitX();
  SceneFigures figures;
  std::vector<double> errors;
  double nees = 0.0;
  for (const DoaMeasurement& doa : doas) {
    EXPECT_EQ(doa.ambiguity, DoaAmbiguity::cone);
    EXPECT_LT((doa.ambiguity_axis - axis).norm(), 1e-9);
    const double true_angle =
        std::acos(std::clamp(axis.dot(truth_direction(truth.sources[0], doa.time_s)), -1.0, 1.0));
    const double error = doa.cone_angle_rad - true_angle;
    errors.push_back(std::abs(error) * 180.0 / std::numbers::pi);
    nees += error * error / doa.cone_angle_variance_rad2;
    figures.min_truth_deg = std::min(figures.min_truth_deg, true_angle * 180.0 / std::numbers::pi);
    figures.max_truth_deg = std::max(figures.max_truth_deg, true_angle * 180.0 / std::numbers::pi);
  }
  figures.doas = static_cast<int>(doas.size());
  if (errors.empty()) return figures;
  std::sort(errors.begin(), errors.end());
  figures.median_error_deg = errors[errors.size() / 2];
  figures.p90_error_deg = errors[errors.size() * 9 / 10];
  figures.mean_nees = nees / static_cast<double>(errors.size());
  return figures;
}

TEST(ConeScene, PassFromOneEndOfTheAxisToTheOther) {
  // 20 m up, 25 m to the side of the axis line, flying along it from 120 m behind to 120 m in
  // front: the cone angle sweeps from ~170 to ~10 deg. A ground reflection at 0.5 (a pair cannot
  // remove it) pulls the angle by its share of the correlation.
  const double yaw = kYawDeg * std::numbers::pi / 180.0;
  const Eigen::Vector3d along(std::cos(yaw), std::sin(yaw), 0.0);
  const Eigen::Vector3d side(-std::sin(yaw), std::cos(yaw), 0.0);
  const Eigen::Vector3d start = -120.0 * along + 25.0 * side + Eigen::Vector3d(0, 0, 20.0);
  const Eigen::Vector3d velocity = 12.0 * along;
  const json trajectory = {{"type", "straight"},
                           {"start_m", {start.x(), start.y(), start.z()}},
                           {"velocity_mps", {velocity.x(), velocity.y(), velocity.z()}}};
  const SceneFigures figures = run_scene(pair_scene(trajectory, 20.0, 0.5));
  std::printf(
      "pair pass: %d DOAs, truth %.1f..%.1f deg, |error| median %.3f p90 %.3f deg, "
      "mean NEES %.2f\n",
      figures.doas, figures.min_truth_deg, figures.max_truth_deg, figures.median_error_deg,
      figures.p90_error_deg, figures.mean_nees);
  EXPECT_GT(figures.doas, 300);
  EXPECT_LT(figures.min_truth_deg, 20.0);
  EXPECT_GT(figures.max_truth_deg, 160.0);
  EXPECT_LT(figures.median_error_deg, 0.3);
  EXPECT_LT(figures.p90_error_deg, 1.0);
  EXPECT_GT(figures.mean_nees, 0.5);
  EXPECT_LT(figures.mean_nees, 4.0);  // overlapping frames, the echo's pull (a pair keeps it)
}

TEST(ConeScene, DroneHoveringAtEndfire) {
  // On the axis line, at the array's height, 80 m out beyond mic 1: the true angle is 0.
  const double yaw = kYawDeg * std::numbers::pi / 180.0;
  const json trajectory = {{"type", "hover"},
                           {"position_m", {80.0 * std::cos(yaw), 80.0 * std::sin(yaw), 1.5}}};
  const SceneFigures figures = run_scene(pair_scene(trajectory, 6.0, 0.0));
  std::printf("pair, hover at endfire: %d DOAs, |error| median %.3f p90 %.3f deg, mean NEES %.2f\n",
              figures.doas, figures.median_error_deg, figures.p90_error_deg, figures.mean_nees);
  EXPECT_GT(figures.doas, 80);
  EXPECT_LT(figures.max_truth_deg, 0.01);
  EXPECT_LT(figures.p90_error_deg, 5.0);
  // A truth exactly on the axis gives NEES ~2 by construction (cone_test's "source exactly at
  // endfire"): the variance is calibrated given the measurement.
  EXPECT_GT(figures.mean_nees, 1.0);
  EXPECT_LT(figures.mean_nees, 3.0);
}

}  // namespace
}  // namespace dronetrack::doa
