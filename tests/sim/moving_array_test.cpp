// Arrays that move (issue 15) against closed forms: the moving-receiver delay (a quadratic), the
// Doppler factor of a moving receiver, the pose file against the trajectory, the validation of
// a moving array's keys, under-water sampling, and fixed arrays rendering exactly as before.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <numbers>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "config/site_config.hpp"
#include "sim/propagation.hpp"
#include "sim_test_util.hpp"

namespace dronetrack::sim::moving_array_test {
namespace {

using nlohmann::json;
using test::channel;
using test::correlation_peak_lag;

constexpr double kWater_mps = 1500.0;
constexpr double kHydrophoneRate_hz = 100000.0;

// Arrival time at a mic moving as m(t) = m0 + v t of the sound a static source s emitted at
// t_e: |s - m0 - v t| = c (t - t_e) squared is
// (v.v - c^2) t^2 + 2 (c^2 t_e - d.v) t + d.d - c^2 t_e^2 = 0 with d = s - m0; the root after t_e.
double moving_receiver_arrival(const Eigen::Vector3d& source, const Eigen::Vector3d& m0,
                               const Eigen::Vector3d& v, double c, double emission_s) {
  const Eigen::Vector3d d = source - m0;
  const double a = v.dot(v) - c * c;
  const double b = 2.0 * (c * c * emission_s - d.dot(v));
  const double cc = d.dot(d) - c * c * emission_s * emission_s;
  const double root = std::sqrt(b * b - 4.0 * a * cc);
  const double r1 = (-b + root) / (2.0 * a);
  const double r2 = (-b - root) / (2.0 * a);
  // a < 0 below Mach 1: one root before t_e (sound that would have to travel backwards).
  return std::max(r1, r2);
}

// A pair of hydrophones 0.6 m apart along the array's x axis.
json hydrophone_pair(const std::string& id) {
  return {{"id", id}, {"mics_m", {{-0.3, 0.0, 0.0}, {0.3, 0.0, 0.0}}}};
}

json broadband(const std::string& id, const Eigen::Vector3d& position) {
  return {{"id", id},
          {"kind", "interferer"},
          {"level_db", 150},
          {"signal", {{"type", "noise"}, {"low_hz", 2000}, {"high_hz", 30000}}},
          {"trajectory",
           {{"type", "hover"}, {"position_m", {position.x(), position.y(), position.z()}}}}};
}

json underwater_scene(const json& arrays, const json& sources, double duration_s) {
  return {{"seed", 3},
          {"sample_rate_hz", kHydrophoneRate_hz},
          {"duration_s", duration_s},
          {"full_scale_db_spl", 200},
          {"site",
           {{"speed_of_sound_mps", kWater_mps},
            {"arrays", arrays},
            {"doa", {{"bands_hz", {{20000, 30000}}}, {"ground_echo", false}, {"frame_s", 0.05}}}}},
          {"sources", sources}};
}

TEST(MovingArray, EmissionTimeSolvesTheMovingReceiverQuadratic) {
  ArrayMotion motion;
  motion.trajectory = Trajectory::straight({-5.0, -12.0, 2.0}, {1.8, 0.6, 0.0});
  motion.yaw_mode = YawMode::fixed;
  motion.yaw_deg = 30.0;
  const Eigen::Vector3d mic_array_m(0.3, 0.0, 0.0);
  const Eigen::Vector3d mic0 = motion.point_state(mic_array_m, 0.0).position_m;
  const Eigen::Vector3d velocity(1.8, 0.6, 0.0);
  const Trajectory source = Trajectory::fixed({14.0, 9.0, 2.0});
  const Receiver receiver = Receiver::carried(motion, mic_array_m);
  const EmissionGrid grid(source, receiver, false, kWater_mps, 0.0, 6.0);
  double worst_s = 0.0;
  for (double emission_s = -0.01; emission_s < 5.9; emission_s += 0.0137) {
    const double arrival_s =
        moving_receiver_arrival({14.0, 9.0, 2.0}, mic0, velocity, kWater_mps, emission_s);
    if (arrival_s < 0.0) continue;
    const EmissionSolution exact =
        solve_emission_time(source, receiver.at(arrival_s), arrival_s, kWater_mps);
    EXPECT_NEAR(exact.emission_time_s, emission_s, 1e-12);
    worst_s = std::max(worst_s, std::abs(grid.emission_time(arrival_s) - emission_s));
  }
  std::printf("moving receiver: grid emission time within %.3f ns of the quadratic\n",
              worst_s * 1e9);
  EXPECT_LT(worst_s, 1e-9);
  // The path is measured to where the mic is at reception, not where it was at emission: the
  // two differ by v (t - t_e) ~ 3 cm here, which the solve must not confuse.
  const double arrival_s =
      moving_receiver_arrival({14.0, 9.0, 2.0}, mic0, velocity, kWater_mps, 1.0);
  const double at_emission_m = (Eigen::Vector3d(14.0, 9.0, 2.0) - (mic0 + velocity)).norm();
  EXPECT_GT(std::abs(kWater_mps * (arrival_s - 1.0) - at_emission_m), 0.01);
}

TEST(MovingArray, BothEndsMovingMatchTheClosedFormAndItsDerivative) {
  // Source p(t) = p0 + v_s t and mic m(t) = m0 + v_m t: for a given arrival t the emission time
  // solves |p0 + v_s t_e - m(t)| = c (t - t_e), a quadratic in t_e; its slope dt_e/dt (the
  // Doppler factor the grid interpolates with) by central differences of that closed form.
  const Eigen::Vector3d p0(-60.0, 25.0, 15.0), source_velocity(14.0, -2.0, 0.5);
  const Trajectory source = Trajectory::straight(p0, source_velocity);
  ArrayMotion motion;
  motion.trajectory = Trajectory::straight({10.0, -5.0, 1.5}, {-6.0, 3.0, 0.0});
  motion.yaw_mode = YawMode::heading;
  const Eigen::Vector3d mic_array_m(0.25, -0.1, 0.3);
  const Receiver receiver = Receiver::carried(motion, mic_array_m);
  constexpr double kAir_mps = 343.0;
  auto closed_form = [&](double t) {
    const Eigen::Vector3d d = p0 - receiver.at(t).position_m;
    const double a = source_velocity.dot(source_velocity) - kAir_mps * kAir_mps;
    const double b = 2.0 * (d.dot(source_velocity) + kAir_mps * kAir_mps * t);
    const double cc = d.dot(d) - kAir_mps * kAir_mps * t * t;
    const double root = std::sqrt(b * b - 4.0 * a * cc);
    return std::min((-b + root) / (2.0 * a), (-b - root) / (2.0 * a));  // the one before t
  };
  for (double t : {0.0, 0.8, 2.5, 7.0}) {
    const EmissionSolution solution = solve_emission_time(source, receiver.at(t), t, kAir_mps);
    EXPECT_NEAR(solution.emission_time_s, closed_form(t), 1e-12) << "t = " << t;
    const double h = 1e-4;
    const double slope = (closed_form(t + h) - closed_form(t - h)) / (2.0 * h);
    EXPECT_NEAR(solution.derivative, slope, 1e-9) << "t = " << t;
    // Both ends matter: the receiver's motion alone moves the slope by ~2 %.
    EXPECT_GT(
        std::abs(solution.derivative -
                 solve_emission_time(source, receiver.at(t).position_m, t, kAir_mps).derivative),
        0.005);
  }
}

TEST(MovingArray, MicVelocityAndDopplerIncludeThePlatformsTurn) {
  // A pair mounted across a vehicle circling at 2 m/s on a 6 m radius (yaw rate 1/3 rad/s): a
  // mic 0.3 m off the axis moves at the vehicle's velocity plus omega x r (0.1 m/s), which the
  // Doppler slope dt_e/dt must carry. Both against central differences of positions and of
  // exactly solved emission times.
  ArrayMotion motion;
  motion.trajectory = Trajectory::circle({0, 0, 2}, 6.0, 2.0, 30.0, false);
  motion.yaw_mode = YawMode::heading;
  motion.yaw_deg = 90.0;
  const Eigen::Vector3d mic_array_m(0.3, 0.0, 0.0);
  const Receiver receiver = Receiver::carried(motion, mic_array_m);
  const Trajectory source = Trajectory::fixed({40.0, 10.0, 2.0});
  const double h = 1e-5;
  for (double t : {0.0, 1.3, 4.0, 9.7}) {
    const TrajectoryState state = receiver.at(t);
    const Eigen::Vector3d numeric =
        (receiver.at(t + h).position_m - receiver.at(t - h).position_m) / (2.0 * h);
    EXPECT_LT((state.velocity_mps - numeric).norm(), 1e-7) << "t = " << t;
    EXPECT_GT((state.velocity_mps - motion.trajectory.at(t).velocity_mps).norm(), 0.09);
    auto emission = [&](double arrival) {
      return solve_emission_time(source, receiver.at(arrival), arrival, kWater_mps).emission_time_s;
    };
    const double slope = (emission(t + h) - emission(t - h)) / (2.0 * h);
    EXPECT_NEAR(solve_emission_time(source, state, t, kWater_mps).derivative, slope, 1e-9)
        << "t = " << t;
  }
}

TEST(MovingArray, InterpolationStaysWithinNanosecondsWhileThePlatformTurns) {
  // Yaw following the heading through tight turns: the mic's velocity jumps where a line meets
  // an arc (the yaw rate does), the worst case for the cubic between grid points.
  ArrayMotion motion;
  motion.trajectory = Trajectory::through_points(
      {{-20, -10, 2}, {20, -10, 2}, {20, 10, 2}, {-20, 10, 2}}, 2.0, 3.0, true);
  motion.yaw_mode = YawMode::heading;
  const Receiver receiver = Receiver::carried(motion, {0.3, 0.0, 0.0});
  const Trajectory source = Trajectory::circle({5, 30, 2}, 10.0, 1.5, 0.0, false);
  const EmissionGrid grid(source, receiver, false, kWater_mps, 0.0, 40.0);
  double worst_s = 0.0;
  for (int n = 0; n < 40 * 4000; ++n) {
    const double t = n / 4000.0 + 0.7e-4;
    const double exact = solve_emission_time(source, receiver.at(t), t, kWater_mps).emission_time_s;
    worst_s = std::max(worst_s, std::abs(grid.emission_time(t) - exact));
  }
  std::printf("turning platform: worst emission-time interpolation error %.3f ns\n", worst_s * 1e9);
  // The mic's velocity jumps by yaw rate x arm = 0.2 m/s at each line/arc joint: the cubic
  // misses a kink of 0.2 / c in slope by about kink x step / 8 = 17 ns (1/600 sample at 100 kHz).
  EXPECT_LT(worst_s, 25e-9);
}

TEST(MovingArray, RecordingShowsTheMovingReceiverDelay) {
  // A fixed reference pair R and a pair M moving at 2 m/s hear one broadband source. The sound R
  // hears at t_R = t_e + |s - r| / c reaches M at the quadratic's root: measured by correlating
  // short windows around each (the Doppler drift across a 10 ms window is under a sample).
  const Eigen::Vector3d source(6.0, 18.0, 2.0);
  const Eigen::Vector3d m_velocity(2.0, 0.0, 0.0);
  json reference = hydrophone_pair("R");
  reference["position_m"] = {0.0, 0.0, 2.0};
  json moving = hydrophone_pair("M");
  moving["trajectory"] = {{"type", "straight"},
                          {"start_m", {-4.0, 4.0, 2.0}},
                          {"velocity_mps", {m_velocity.x(), 0.0, 0.0}}};
  moving["yaw"] = "fixed";
  const Scenario scenario =
      parse_scenario(underwater_scene(json::array({reference, moving}),
                                      json::array({broadband("S", source)}), 1.0),
                     ".");
  const RenderedScene scene = render_scene(scenario);
  const Eigen::Vector3d r0(-0.3, 0.0, 2.0);  // R's mic 0
  const Eigen::Vector3d m0(-4.3, 4.0, 2.0);  // M's mic 0 at t = 0
  const auto window = static_cast<std::size_t>(0.01 * kHydrophoneRate_hz);
  for (double emission_s : {0.2, 0.5, 0.8}) {
    const double t_r = emission_s + (source - r0).norm() / kWater_mps;
    const double t_m = moving_receiver_arrival(source, m0, m_velocity, kWater_mps, emission_s);
    const auto n_r = static_cast<std::size_t>(std::lround(t_r * kHydrophoneRate_hz));
    const auto n_m = static_cast<std::size_t>(std::lround(t_m * kHydrophoneRate_hz));
    const auto r = channel(scene.arrays[0], 0, n_r - window / 2, n_r + window / 2);
    const auto m = channel(scene.arrays[1], 0, n_m - window / 2, n_m + window / 2);
    // Lag of M's window against R's: (t_m - t_r) less the whole samples already taken out.
    const double expected =
        (t_m - t_r) * kHydrophoneRate_hz - (static_cast<double>(n_m) - static_cast<double>(n_r));
    const double lag =
        correlation_peak_lag(m, r, expected, 2.0, 2000.0, 30000.0, kHydrophoneRate_hz);
    EXPECT_NEAR(lag / kHydrophoneRate_hz, expected / kHydrophoneRate_hz, 0.2e-6)
        << "emission at " << emission_s << " s";
  }
}

TEST(MovingArray, ToneRecordedOnTheMoveIsDopplerShifted) {
  // A static 2 kHz tone heard from a platform passing at 20 m/s in air: f (1 + u.v_m / c), u
  // from the mic toward the source.
  const Eigen::Vector3d source(0.0, 15.0, 5.0);
  const Eigen::Vector3d velocity(20.0, 0.0, 0.0);
  json array = {{"id", "A1"},
                {"mics_m", {{0.0, 0.0, 0.0}, {0.2, 0.0, 0.0}}},
                {"trajectory",
                 {{"type", "straight"},
                  {"start_m", {-40.0, 0.0, 1.5}},
                  {"velocity_mps", {velocity.x(), velocity.y(), velocity.z()}}}}};
  json document = {
      {"seed", 1},
      {"duration_s", 3.0},
      {"site", {{"speed_of_sound_mps", 343.0}, {"arrays", {array}}}},
      {"sources",
       {{{"id", "T"},
         {"level_db", 90},
         {"signal", {{"type", "tones"}, {"frequencies_hz", {2000.0}}}},
         {"trajectory",
          {{"type", "hover"}, {"position_m", {source.x(), source.y(), source.z()}}}}}}}};
  const Scenario scenario = parse_scenario(document, ".");
  const RenderedArray rendered = render_array(scenario, 0);
  for (double centre_s : {0.5, 2.5}) {
    const auto begin = static_cast<std::size_t>((centre_s - 0.1) * 48000.0);
    const double measured_hz = test::strongest_frequency_hz(
        channel(rendered, 0, begin, begin + 9600), 1800.0, 2200.0, 48000.0);
    const Eigen::Vector3d mic = Eigen::Vector3d(-40.0, 0.0, 1.5) + velocity * centre_s;
    const Eigen::Vector3d u = (source - mic).normalized();
    const double predicted_hz = 2000.0 * (1.0 + u.dot(velocity) / 343.0);
    EXPECT_NEAR(measured_hz - 2000.0, predicted_hz - 2000.0, 0.01 * std::abs(predicted_hz - 2000.0))
        << "at " << centre_s << " s";
  }
}

TEST(MovingArray, PoseFileFollowsTheTrajectoryAndTheSiteReferencesIt) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("sim_pose_test_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  // Counter-clockwise circle of radius 20 m at 2 m/s from the east point: heading = 90 deg +
  // 0.1 rad/s * t; the pair is mounted across the hull (yaw offset 90) and pitched 5 deg.
  json moving = hydrophone_pair("H");
  moving["trajectory"] = {
      {"type", "circle"}, {"centre_m", {10.0, 0.0, 2.0}}, {"radius_m", 20.0}, {"speed_mps", 2.0}};
  moving["yaw_deg"] = 90.0;
  moving["pitch_deg"] = 5.0;
  moving["pose_rate_hz"] = 10.0;
  const Scenario scenario = parse_scenario(
      underwater_scene(json::array({moving}), json::array({broadband("S", {0, 40, 2})}), 0.95),
      ".");
  const WrittenScene written = write_scene(scenario, dir);
  ASSERT_EQ(written.poses.size(), 1u);
  EXPECT_EQ(written.poses[0], dir / "H.pose.jsonl");
  std::ifstream pose_stream(written.poses[0]);
  std::string line;
  int count = 0;
  while (std::getline(pose_stream, line)) {
    const json pose = json::parse(line);
    const double t = 0.1 * count;
    EXPECT_NEAR(pose["t"].get<double>(), t, 1e-12);
    const double angle = 0.1 * t;  // rad travelled round the circle
    EXPECT_NEAR(pose["position_m"][0].get<double>(), 10.0 + 20.0 * std::cos(angle), 1e-9);
    EXPECT_NEAR(pose["position_m"][1].get<double>(), 20.0 * std::sin(angle), 1e-9);
    EXPECT_NEAR(pose["position_m"][2].get<double>(), 2.0, 1e-12);
    // Heading 90 deg + the angle travelled, plus the 90 deg mounting, in (-180, 180].
    double yaw_deg = 180.0 + angle * 180.0 / std::numbers::pi;
    if (yaw_deg > 180.0) yaw_deg -= 360.0;
    EXPECT_NEAR(pose["yaw_deg"].get<double>(), yaw_deg, 1e-9);
    EXPECT_EQ(pose["pitch_deg"].get<double>(), 5.0);
    EXPECT_EQ(pose["roll_deg"].get<double>(), 0.0);
    ++count;
  }
  EXPECT_EQ(count, 11);  // t = 0 .. 1.0 s: covers the whole 0.95 s recording
  std::ifstream site_stream(written.site);
  const json site = json::parse(site_stream);
  EXPECT_EQ(site["arrays"][0]["pose_file"], "H.pose.jsonl");
  EXPECT_FALSE(site["arrays"][0].contains("trajectory"));
  EXPECT_NEAR(site["arrays"][0]["position_m"][0].get<double>(), 30.0, 1e-9);
  EXPECT_NEAR(site["arrays"][0]["yaw_deg"].get<double>(), 180.0, 1e-9);
  std::ifstream truth_stream(written.truth);
  const json truth = json::parse(truth_stream);
  EXPECT_EQ(truth["arrays"]["H"]["pose_file"], "H.pose.jsonl");
  // Truth directions point from where the pair's centre is at each time.
  const double t = 0.5;
  const Eigen::Vector3d centre(10.0 + 20.0 * std::cos(0.1 * t), 20.0 * std::sin(0.1 * t), 2.0);
  const json& direction = truth["interferers"][0]["doa"]["H"]["direction"][50];
  const Eigen::Vector3d expected = (Eigen::Vector3d(0, 40, 2) - centre).normalized();
  EXPECT_NEAR(direction[0].get<double>(), expected.x(), 1e-9);
  EXPECT_NEAR(direction[1].get<double>(), expected.y(), 1e-9);
  // The written site loads (recordings checked: 100 kHz, 2 channels, 20-30 kHz band).
  std::vector<std::string> warnings;
  const config::SiteConfig loaded = config::load_site_config(written.site, warnings);
  EXPECT_EQ(loaded.arrays.size(), 1u);
  std::filesystem::remove_all(dir);
}

TEST(MovingArray, HydrophonePairAtOneHundredKilohertzKeepsExactDelays) {
  // Under water: c = 1500 m/s, 100 kHz, a 20-30 kHz source, hydrophones 0.6 m apart.
  const Eigen::Vector3d position(9.0, 31.0, 2.0);
  json source = broadband("S", position);
  source["signal"] = {{"type", "noise"}, {"low_hz", 20000}, {"high_hz", 30000}};
  json pair = hydrophone_pair("H");
  pair["position_m"] = {0.0, 0.0, 2.0};
  pair["yaw_deg"] = 20.0;
  const Scenario scenario =
      parse_scenario(underwater_scene(json::array({pair}), json::array({source}), 0.2), ".");
  const RenderedArray rendered = render_array(scenario, 0);
  const auto& geometry = scenario.site.arrays[0].geometry;
  const double expected_s =
      ((position - geometry.mic_site_m(0)).norm() - (position - geometry.mic_site_m(1)).norm()) /
      kWater_mps;
  const double measured_s =
      correlation_peak_lag(channel(rendered, 0, 2000), channel(rendered, 1, 2000),
                           expected_s * kHydrophoneRate_hz, 3.0, 20000.0, 30000.0,
                           kHydrophoneRate_hz) /
      kHydrophoneRate_hz;
  EXPECT_NEAR(measured_s, expected_s, 0.05e-6);
}

// FNV-1a over the bytes of the samples.
std::uint64_t fingerprint(const std::vector<float>& samples) {
  std::uint64_t hash = 0xcbf29ce484222325ULL;
  for (float value : samples) {
    unsigned char bytes[sizeof(float)];
    std::memcpy(bytes, &value, sizeof(float));
    for (unsigned char byte : bytes) hash = (hash ^ byte) * 0x100000001b3ULL;
  }
  return hash;
}

TEST(MovingArray, FixedArrayRendersBitIdenticallyToBefore) {
  // A circling drone with a ground echo, a static interferer and sensor noise at a fixed
  // array; the fingerprint is of the same scene rendered by the simulator before arrays could
  // move (main at 00a49e0, `dronetrack sim`), bit for bit. A deliberate change to the rendering
  // updates it: FNV-1a 64 of the float samples, printed by the failure.
  const json document = json::parse(R"({
    "seed": 5, "sample_rate_hz": 48000, "duration_s": 0.25,
    "ground": {"reflection_coefficient": 0.5},
    "site": {"speed_of_sound_mps": 343.0, "arrays": [{"id": "A1", "position_m": [0, 0, 1.5],
      "yaw_deg": 30, "mics_m": [[0, 0, 0.5], [0.4714, 0, -0.1667], [-0.2357, 0.4082, -0.1667],
                                [-0.2357, -0.4082, -0.1667]]}]},
    "sources": [{"id": "D1", "level_db": 80, "trajectory": {"type": "circle",
                  "centre_m": [10, 5, 20], "radius_m": 15, "speed_mps": 12}},
                {"id": "G1", "kind": "interferer", "level_db": 70,
                 "trajectory": {"type": "hover", "position_m": [-8, 3, 1]}}],
    "noise": {"sensor": {"level_db": 30}}})");
  const RenderedScene scene = render_scene(parse_scenario(document, "."));
  ASSERT_EQ(scene.scale, 1.0);
  EXPECT_EQ(scene.arrays[0].samples[1000 * 4 + 1], -0x1.1989720000000p-12f);
  EXPECT_EQ(fingerprint(scene.arrays[0].samples), 0xc4bb3c537e203764ULL);
}

std::string first_problem(const json& document) {
  try {
    parse_scenario(document, ".");
  } catch (const config::ConfigError& failure) {
    return failure.problems().front();
  }
  return "";
}

TEST(MovingArray, BadMovingArrayKeysNameTheirPath) {
  auto scene_with = [](const json& array) {
    return underwater_scene(json::array({array}), json::array({broadband("S", {0, 40, 2})}), 10.0);
  };
  json hovering = hydrophone_pair("H");
  hovering["trajectory"] = {{"type", "hover"}, {"position_m", {0, 0, 2}}};
  EXPECT_EQ(first_problem(scene_with(hovering)).rfind("site.arrays[0].yaw: \"heading\" needs", 0),
            0u);
  json misplaced = hydrophone_pair("H");
  misplaced["trajectory"] = {
      {"type", "straight"}, {"start_m", {0, 0, 2}}, {"velocity_mps", {1, 0, 0}}};
  misplaced["position_m"] = {5, 0, 2};
  EXPECT_EQ(first_problem(scene_with(misplaced)).rfind("site.arrays[0].position_m: differs", 0),
            0u);
  json spinning = hydrophone_pair("H");  // 10 m/s round a 2 m circle: 286 deg/s
  spinning["trajectory"] = {
      {"type", "circle"}, {"centre_m", {0, 0, 2}}, {"radius_m", 2.0}, {"speed_mps", 10.0}};
  spinning["pose_rate_hz"] = 5;
  EXPECT_EQ(
      first_problem(scene_with(spinning)).rfind("site.arrays[0].pose_rate_hz: the array turns", 0),
      0u);
  spinning["pose_rate_hz"] = 10;  // 28.6 deg per line: fine
  EXPECT_EQ(first_problem(scene_with(spinning)), "");
  json fixed = hydrophone_pair("H");
  fixed["position_m"] = {0, 0, 2};
  fixed["yaw"] = "heading";
  EXPECT_EQ(first_problem(scene_with(fixed)),
            "site.arrays[0].yaw: only for a moving array (one with a trajectory)");
  json unknown = hydrophone_pair("H");
  unknown["trajectory"] = {{"type", "zigzag"}};
  EXPECT_EQ(first_problem(scene_with(unknown)).rfind("site.arrays[0].trajectory.type:", 0), 0u);
}

TEST(MovingArray, RenderingLongerThanCheckedStillRefusesATooFastTurn) {
  // 5 m/s into a 90-degree corner of radius 1 m at t = 4 s (286 deg/s, 57 deg per line at
  // 5 Hz): fine over the scenario's 2 s, refused when stretched to 6 s (as --duration-s does),
  // before anything is rendered or written.
  json pair = hydrophone_pair("H");
  pair["trajectory"] = {{"type", "waypoints"},
                        {"points_m", {{0, 0, 2}, {20, 0, 2}, {20, 20, 2}}},
                        {"speed_mps", 5.0},
                        {"turn_radius_m", 1.0}};
  pair["pose_rate_hz"] = 5;
  Scenario scenario = parse_scenario(
      underwater_scene(json::array({pair}), json::array({broadband("S", {0, 40, 2})}), 2.0), ".");
  scenario.duration_s = 6.0;
  const auto dir =
      std::filesystem::temp_directory_path() / ("sim_turn_test_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  try {
    write_scene(scenario, dir);
    ADD_FAILURE() << "a 57-degree step between pose lines was written";
  } catch (const std::runtime_error& failure) {
    EXPECT_EQ(std::string(failure.what()).rfind("array H turns ", 0), 0u) << failure.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "H.wav"));
  EXPECT_FALSE(std::filesystem::exists(dir / "H.pose.jsonl"));
  std::filesystem::remove_all(dir);
}

TEST(MovingArray, SampleRateBoundsAreTheSiteConfigs) {
  // Whatever replay reads (1 kHz to 1 MHz), the simulator writes.
  json source = broadband("S", {0, 40, 2});
  source["signal"] = {{"type", "noise"}, {"low_hz", 100}, {"high_hz", 400}};
  json pair = hydrophone_pair("H");
  pair["position_m"] = {0, 0, 2};
  json document = underwater_scene(json::array({pair}), json::array({source}), 1.0);
  document["site"]["doa"]["bands_hz"] = {{100, 400}};
  for (double rate_hz : {1000.0, 1e6}) {
    document["sample_rate_hz"] = rate_hz;
    EXPECT_EQ(first_problem(document), "") << rate_hz;
  }
  document["sample_rate_hz"] = 1.1e6;
  EXPECT_EQ(first_problem(document).rfind("sample_rate_hz: must be in [1000, 1e+06]", 0), 0u)
      << first_problem(document);
}

}  // namespace
}  // namespace dronetrack::sim::moving_array_test
