// The physics against closed forms: inter-mic delays of a static source, Doppler of a pass, the
// ground reflection's extra delay, emission-time interpolation and truth directions.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "sim/propagation.hpp"
#include "sim_test_util.hpp"

namespace dronetrack::sim::propagation_test {
namespace {

using nlohmann::json;
using test::channel;
using test::correlation_peak_lag;
using test::scene;

constexpr double kC = 343.0;
constexpr double kFs = 48000.0;

// Closed form for a straight, constant-velocity path p(t) = p0 + v t: |p0 + v te - m| = c (t - te)
// is a quadratic in te; the root with te <= t.
double straight_emission_time(const Eigen::Vector3d& p0, const Eigen::Vector3d& v,
                              const Eigen::Vector3d& m, double t) {
  const Eigen::Vector3d d = p0 - m;
  // |d + v te|^2 = c^2 (t - te)^2  ->  (v.v - c^2) te^2 + 2 (d.v + c^2 t) te + d.d - c^2 t^2 = 0
  const double a = v.dot(v) - kC * kC;
  const double b = 2.0 * (d.dot(v) + kC * kC * t);
  const double cc = d.dot(d) - kC * kC * t * t;
  const double root = std::sqrt(b * b - 4.0 * a * cc);
  const double r1 = (-b + root) / (2.0 * a);
  const double r2 = (-b - root) / (2.0 * a);
  // Below Mach 1 one root is in the past (the retarded time), the other in the future.
  return r1 <= t ? (r2 <= t ? std::max(r1, r2) : r1) : r2;
}

TEST(Propagation, StaticSourcePairDelaysMatchGeometryWithinOneMicrosecond) {
  for (const auto& position :
       {json{12.0, 5.0, 9.0}, json{-30.0, 40.0, 25.0}, json{3.0, -4.0, 1.0}}) {
    json source = {{"id", "S"},
                   {"kind", "interferer"},
                   {"level_db", 90},
                   {"signal", {{"type", "noise"}, {"low_hz", 300}, {"high_hz", 8000}}},
                   {"trajectory", {{"type", "hover"}, {"position_m", position}}}};
    const Scenario scenario = parse_scenario(scene(source, 1.0), ".");
    const RenderedArray array = render_array(scenario, 0);
    const auto& geometry = scenario.site.arrays[0].geometry;
    const Eigen::Vector3d p(position[0].get<double>(), position[1].get<double>(),
                            position[2].get<double>());
    for (std::size_t i = 0; i < 4; ++i) {
      for (std::size_t j = i + 1; j < 4; ++j) {
        const double expected_s =
            ((p - geometry.mic_site_m(i)).norm() - (p - geometry.mic_site_m(j)).norm()) / kC;
        const double measured_s =
            correlation_peak_lag(channel(array, i, 4800), channel(array, j, 4800), expected_s * kFs,
                                 3.0) /
            kFs;
        EXPECT_NEAR(measured_s, expected_s, 1e-6) << "pair " << i << "-" << j;
        EXPECT_NEAR(measured_s, expected_s, 0.05e-6)
            << "pair " << i << "-" << j << " (expected far better than 1 us)";
      }
    }
  }
}

TEST(Propagation, PassShowsPredictedDopplerShift) {
  // A 2 kHz tone flying past at 25 m/s: received frequency f / (1 + u.v / c).
  const Eigen::Vector3d start(-40.0, 8.0, 20.0), velocity(25.0, 0.0, 0.0);
  json source = {{"id", "D1"},
                 {"level_db", 90},
                 {"signal", {{"type", "tones"}, {"frequencies_hz", {2000.0}}}},
                 {"trajectory",
                  {{"type", "straight"},
                   {"start_m", {start.x(), start.y(), start.z()}},
                   {"velocity_mps", {velocity.x(), velocity.y(), velocity.z()}}}}};
  const Scenario scenario = parse_scenario(scene(source, 3.0), ".");
  const RenderedArray array = render_array(scenario, 0);
  const Eigen::Vector3d mic = scenario.site.arrays[0].geometry.mic_site_m(0);
  for (double centre_s : {0.5, 2.5}) {
    // Frequency of the strongest line in a 0.2 s window, by Newton on the zero-padded spectrum.
    const auto begin = static_cast<std::size_t>((centre_s - 0.1) * kFs);
    const auto x = channel(array, 0, begin, begin + static_cast<std::size_t>(0.2 * kFs));
    double best_hz = 0.0, best_power = 0.0;
    auto power_at = [&](double f) {
      std::complex<double> sum = 0.0;
      for (std::size_t n = 0; n < x.size(); ++n) {
        const double w = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * (n + 0.5) / x.size());
        sum += w * x[n] * std::polar(1.0, -2.0 * std::numbers::pi * f * n / kFs);
      }
      return std::norm(sum);
    };
    for (double f = 1800.0; f <= 2200.0; f += 0.5) {
      const double power = power_at(f);
      if (power > best_power) best_power = power, best_hz = f;
    }
    for (double step = 0.25; step > 1e-4; step /= 2.0) {
      if (power_at(best_hz + step) > best_power)
        best_hz += step, best_power = power_at(best_hz);
      else if (power_at(best_hz - step) > best_power)
        best_hz -= step, best_power = power_at(best_hz);
    }
    const double te = straight_emission_time(start, velocity, mic, centre_s);
    const Eigen::Vector3d u = (start + velocity * te - mic).normalized();
    const double predicted_hz = 2000.0 / (1.0 + u.dot(velocity) / kC);
    EXPECT_NEAR(best_hz, predicted_hz, 0.005 * predicted_hz);
    // The shift itself (~+-140 Hz) within 1 %.
    EXPECT_NEAR(best_hz - 2000.0, predicted_hz - 2000.0, 0.01 * std::abs(predicted_hz - 2000.0))
        << "at " << centre_s << " s";
  }
}

TEST(Propagation, GroundReflectionArrivesWithTheImageSourceDelay) {
  // Broadband source; a mic's autocorrelation has a side peak at the extra path of the image.
  const Eigen::Vector3d p(25.0, 10.0, 12.0);
  json source = {{"id", "S"},
                 {"kind", "interferer"},
                 {"level_db", 90},
                 {"signal", {{"type", "noise"}, {"low_hz", 200}, {"high_hz", 12000}}},
                 {"trajectory", {{"type", "hover"}, {"position_m", {p.x(), p.y(), p.z()}}}}};
  json document = scene(source, 1.0);
  document["ground"] = {{"reflection_coefficient", 0.6}};
  const Scenario scenario = parse_scenario(document, ".");
  const RenderedArray array = render_array(scenario, 0);
  for (std::size_t mic = 0; mic < 4; ++mic) {
    const Eigen::Vector3d m = scenario.site.arrays[0].geometry.mic_site_m(mic);
    const double direct_m = (p - m).norm();
    const double image_m = (mirror_in_ground(p) - m).norm();
    const double expected_s = (image_m - direct_m) / kC;
    const auto x = channel(array, mic, 2400);
    const double lag_s = correlation_peak_lag(x, x, expected_s * kFs, 2.0) / kFs;
    EXPECT_NEAR(lag_s, expected_s, 1e-6) << "mic " << mic;
  }
}

TEST(Propagation, EmissionTimeSolveMatchesClosedForm) {
  const Trajectory trajectory = Trajectory::straight({-100.0, 30.0, 40.0}, {18.0, -3.0, 1.0});
  const Eigen::Vector3d mic(1.0, 2.0, 1.5);
  for (double t : {-1.0, 0.0, 0.37, 5.0, 12.5}) {
    const double expected = straight_emission_time({-100.0, 30.0, 40.0}, {18.0, -3.0, 1.0}, mic, t);
    EXPECT_NEAR(solve_emission_time(trajectory, mic, t, kC).emission_time_s, expected, 1e-12);
  }
}

TEST(Propagation, InterpolatedEmissionTimesStayWithinNanosecondsOfExactSolve) {
  // Worst case for the cubic between grid points: the acceleration jumps where a line meets a
  // corner arc. A fast drone (20 m/s) turning tightly (radius 3 m: 133 m/s^2).
  std::vector<Eigen::Vector3d> corners{{-20, -10, 15}, {20, -10, 15}, {20, 10, 25}, {-20, 10, 15}};
  const Trajectory trajectory = Trajectory::through_points(corners, 20.0, 3.0, true);
  const Eigen::Vector3d mic(2.0, -30.0, 1.5);
  const EmissionGrid grid(trajectory, mic, false, kC, 0.0, 12.0);
  double worst_s = 0.0;
  for (int n = 0; n < 12 * 4800; ++n) {  // every 10th output sample
    const double t = n * 10.0 / kFs + 0.3e-4;
    const double exact = solve_emission_time(trajectory, mic, t, kC).emission_time_s;
    worst_s = std::max(worst_s, std::abs(grid.emission_time(t) - exact));
  }
  RecordProperty("worst_interpolation_error_ns", std::to_string(worst_s * 1e9));
  std::printf("emission-time interpolation: worst error %.3f ns over 12 s of tight turns\n",
              worst_s * 1e9);
  EXPECT_LT(worst_s, 10e-9);
  // And on a smooth path it is far smaller still.
  const Trajectory circle = Trajectory::circle({0, 0, 30}, 40.0, 15.0, 0.0, false);
  const EmissionGrid circle_grid(circle, mic, true, kC, 0.0, 5.0);
  double circle_worst_s = 0.0;
  for (int n = 0; n < 5 * 4800; ++n) {
    const double t = n * 10.0 / kFs + 0.3e-4;
    const double exact = solve_emission_time(circle, mic, t, kC, true).emission_time_s;
    circle_worst_s = std::max(circle_worst_s, std::abs(circle_grid.emission_time(t) - exact));
  }
  EXPECT_LT(circle_worst_s, 0.1e-9);
}

TEST(Propagation, TruthDirectionsPointWhereTheSoundLeftTheSource) {
  // Independent check: closed-form emission time for a straight pass, direction from the mic
  // centroid; also differs measurably from the naive "where it is now".
  const Eigen::Vector3d start(-150.0, 60.0, 50.0), velocity(20.0, 0.0, 0.0);
  json source = {{"id", "D1"},
                 {"level_db", 90},
                 {"trajectory",
                  {{"type", "straight"},
                   {"start_m", {start.x(), start.y(), start.z()}},
                   {"velocity_mps", {velocity.x(), velocity.y(), velocity.z()}}}}};
  const Scenario scenario = parse_scenario(scene(source, 10.0), ".");
  const Truth truth = compute_truth(scenario);
  ASSERT_EQ(truth.sources.size(), 1u);
  const auto& d1 = truth.sources[0];
  ASSERT_EQ(d1.t_s.size(), 1001u);
  EXPECT_DOUBLE_EQ(d1.t_s[1], 0.01);
  const Eigen::Vector3d centre = scenario.site.arrays[0].geometry.centre_site_m();
  double largest_lag_deg = 0.0;
  for (std::size_t i = 0; i < d1.t_s.size(); i += 7) {
    const double t = d1.t_s[i];
    const double te = straight_emission_time(start, velocity, centre, t);
    const Eigen::Vector3d expected = (start + velocity * te - centre).normalized();
    EXPECT_LT((d1.direction[0][i] - expected).norm(), 1e-9) << "t = " << t;
    EXPECT_LT((d1.position_m[i] - (start + velocity * t)).norm(), 1e-9);
    EXPECT_LT((d1.velocity_mps[i] - velocity).norm(), 1e-9);
    const Eigen::Vector3d now = (start + velocity * t - centre).normalized();
    largest_lag_deg = std::max(
        largest_lag_deg, std::acos(std::min(1.0, now.dot(expected))) * 180 / std::numbers::pi);
  }
  EXPECT_GT(largest_lag_deg, 2.0);  // the correction matters at 160 m and 20 m/s
}

}  // namespace
}  // namespace dronetrack::sim::propagation_test
