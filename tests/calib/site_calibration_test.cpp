// The site calibration against known injected errors: synthetic flights (exact geometry,
// Gaussian TDOA and GPS noise), recovered estimates checked against the truth and their own
// reported standard deviations.
#include "calib/site_calibration.hpp"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "calib/channel_gains.hpp"
#include "tests/calib/synthetic_flight.hpp"

namespace dronetrack::calib {
namespace {

using testing::FlightSettings;
using testing::InjectedErrors;

CalibrationSettings settings_for(const CalibrationPriors& priors, const FlightSettings& flight) {
  CalibrationSettings settings;
  settings.priors = priors;
  settings.speed_of_sound_mps = flight.speed_of_sound_mps;
  settings.reference_position_std_m = flight.gps_std_m;
  return settings;
}

// Every estimated scalar against its truth: (estimate - truth) / std.
struct Comparison {
  std::vector<double> normalised;  // of every free scalar
  std::vector<std::string> names;
};

void add(Comparison& out, const std::string& name, const Estimate& estimate, double truth) {
  if (estimate.prior_std <= 0.0) return;
  out.normalised.push_back((estimate.value - truth) / estimate.std);
  out.names.push_back(name);
}

Comparison compare(const std::vector<ArrayNominal>& arrays,
                   const std::vector<InjectedErrors>& errors, const CalibrationResult& result) {
  Comparison out;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    const ArrayCalibration& got = result.arrays[a];
    const ArrayNominal& nominal = arrays[a];
    const InjectedErrors& truth = errors[a];
    const std::string id = nominal.id + ".";
    add(out, id + "yaw", got.yaw_deg, nominal.yaw_deg + truth.attitude_deg(0));
    add(out, id + "pitch", got.pitch_deg, nominal.pitch_deg + truth.attitude_deg(1));
    add(out, id + "roll", got.roll_deg, nominal.roll_deg + truth.attitude_deg(2));
    for (int k = 0; k < 3; ++k)
      add(out, id + "position" + std::to_string(k), got.position_m[static_cast<std::size_t>(k)],
          nominal.position_m(k) + truth.position_m(k));
    for (std::size_t i = 0; i < nominal.mics_m.size(); ++i) {
      for (int k = 0; k < 3; ++k)
        add(out, id + "mic" + std::to_string(i) + "." + std::to_string(k),
            got.mic_position_m[i][static_cast<std::size_t>(k)],
            nominal.mics_m[i](k) + truth.mic_offsets_m[i](k));
      add(out, id + "delay" + std::to_string(i), got.channel_delay_s[i], truth.channel_delay_s[i]);
    }
    add(out, id + "clock", got.clock_offset_s, truth.clock_offset_s);
  }
  return out;
}

CalibrationPriors field_priors() {
  CalibrationPriors priors;
  priors.attitude_std_deg = 2.0;
  priors.array_position_std_m = 0.05;
  priors.channel_delay_std_s = 1e-4;
  priors.clock_offset_std_s = 5e-3;
  return priors;
}

// The issue's field errors, chosen, not drawn: 2 degrees of yaw, a tilted mast, 3 mm mics,
// 0.1 ms channel skew, 5 ms clock. Each comes back within 3 of its reported std, the attitude
// and skew well inside what mattered, and the residuals fall to the TDOA noise.
TEST(SiteCalibration, RecoversTheIssuesFieldErrors) {
  const std::vector<ArrayNominal> arrays = testing::two_arrays(0.003);
  std::vector<InjectedErrors> errors(2);
  std::mt19937_64 random(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::size_t a = 0; a < 2; ++a) {
    const double sign = a == 0 ? 1.0 : -1.0;
    errors[a].attitude_deg = {2.0 * sign, -1.0 * sign, 0.7};
    errors[a].position_m = {0.03 * sign, -0.02, 0.01};
    for (int i = 0; i < 4; ++i) {
      errors[a].mic_offsets_m.emplace_back(0.003 * normal(random), 0.003 * normal(random),
                                           0.003 * normal(random));
      errors[a].channel_delay_s.push_back(i == 0 ? 0.0 : 1e-4 * sign * (i % 2 ? 1.0 : -0.5));
    }
    errors[a].clock_offset_s = 5e-3 * sign;
  }
  FlightSettings flight_settings;
  flight_settings.duration_s = 60.0;
  const testing::Flight flight =
      testing::fly(arrays, errors, testing::looping_path, flight_settings, random);
  const CalibrationResult result =
      calibrate_site(arrays, flight.frames, ReferenceTrack(flight.gps, 1.0),
                     settings_for(field_priors(), flight_settings));

  std::printf(
      "residual rms before %.2f us, after %.2f us (TDOA noise %.2f us, estimated %.2f us)\n",
      result.before.rms_s * 1e6, result.after.rms_s * 1e6, flight_settings.tdoa_std_s * 1e6,
      result.tdoa_std_s * 1e6);
  const Comparison comparison = compare(arrays, errors, result);
  for (std::size_t k = 0; k < comparison.normalised.size(); ++k)
    EXPECT_LT(std::abs(comparison.normalised[k]), 3.5) << comparison.names[k];
  for (const ArrayCalibration& array : result.arrays) {
    std::printf(
        "%s: yaw %.3f +- %.3f deg, pitch %.3f +- %.3f, roll %.3f +- %.3f, clock %.2f +- %.2f ms\n",
        array.id.c_str(), array.yaw_deg.value, array.yaw_deg.std, array.pitch_deg.value,
        array.pitch_deg.std, array.roll_deg.value, array.roll_deg.std,
        array.clock_offset_s.value * 1e3, array.clock_offset_s.std * 1e3);
    // A turn of the whole array and the same turn of its four mics move the same pair delays:
    // the attitude is known to about what the mic prior allows (3 mm over a 0.5 m arm, 0.34
    // degrees), the mics' geometry in the site frame far better (below).
    EXPECT_LT(array.yaw_deg.std, 0.3);
    EXPECT_TRUE(array.yaw_deg.excited);
    EXPECT_TRUE(array.pitch_deg.excited);
    EXPECT_TRUE(array.roll_deg.excited);
    for (std::size_t i = 1; i < 4; ++i) {
      EXPECT_LT(array.channel_delay_s[i].std, 1e-5);  // 0.1 ms skew to under half a sample
      EXPECT_TRUE(array.channel_delay_s[i].excited);
    }
  }
  // What the DOA sees: each mic's site position relative to the array's centre.
  for (std::size_t a = 0; a < 2; ++a) {
    const auto relative = [](std::vector<Eigen::Vector3d> mics) {
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      for (const auto& mic : mics) centre += mic;
      for (auto& mic : mics) mic -= centre / static_cast<double>(mics.size());
      return mics;
    };
    InjectedErrors none;
    none.mic_offsets_m.assign(4, Eigen::Vector3d::Zero());
    const auto truth = relative(testing::true_mics_site(arrays[a], errors[a]));
    const auto nominal = relative(testing::true_mics_site(arrays[a], none));
    const auto calibrated = relative(testing::true_mics_site(result.arrays[a].calibrated, none));
    double before_m2 = 0.0, after_m2 = 0.0;
    for (std::size_t i = 0; i < 4; ++i) {
      before_m2 += (nominal[i] - truth[i]).squaredNorm() / 4.0;
      after_m2 += (calibrated[i] - truth[i]).squaredNorm() / 4.0;
    }
    std::printf("%s: mic geometry error rms %.2f mm before, %.2f mm after\n", arrays[a].id.c_str(),
                std::sqrt(before_m2) * 1e3, std::sqrt(after_m2) * 1e3);
    EXPECT_LT(std::sqrt(after_m2), 0.1 * std::sqrt(before_m2));
  }
  EXPECT_GT(result.before.rms_s, 4.0 * flight_settings.tdoa_std_s);
  EXPECT_LT(result.after.rms_s, 1.1 * flight_settings.tdoa_std_s);
  EXPECT_NEAR(result.tdoa_std_s, flight_settings.tdoa_std_s, 0.15 * flight_settings.tdoa_std_s);
}

// A skew of 0.1-0.3 ms between channels makes the uncorrected node take a neighbouring cycle of
// the rotor's harmonic (400 us away in a 1.5-3.5 kHz band) for many directions, for stretches
// of the flight. Here 60 % of one array's frames have mic 0's pairs a cycle off, half each way
// (seed 18's A2 in the field scenes: 69 % of its frames off); the skew still comes back and the
// wrong frames are set aside. (The field's wrong frames also fit the nominal array tilted by
// degrees, which locked the solve from zero delays; the densest-cluster start that cures it is
// checked end to end on those seeds, docs/calibration.md.)
TEST(SiteCalibration, ASkewFoundThroughAMajorityOfWrongCycleFrames) {
  const std::vector<ArrayNominal> arrays = testing::two_arrays(0.003);
  std::vector<InjectedErrors> errors(2);
  const std::vector<double> skew_s = {0.0, -296e-6, -183e-6, -110e-6};
  for (std::size_t a = 0; a < 2; ++a) {
    errors[a].attitude_deg = {0.7, 0.0, 0.0};
    for (std::size_t i = 0; i < 4; ++i) {
      errors[a].mic_offsets_m.emplace_back(0.002, -0.001, 0.001 * static_cast<double>(i));
      errors[a].channel_delay_s.push_back(a == 0 ? skew_s[i] : 0.0);
    }
  }
  FlightSettings flight_settings;
  flight_settings.duration_s = 60.0;
  std::mt19937_64 random(18);
  testing::Flight flight =
      testing::fly(arrays, errors, testing::looping_path, flight_settings, random);
  constexpr double kCycle_s = 400e-6;
  int replaced = 0, of_array = 0;
  for (TdoaFrame& frame : flight.frames) {
    if (frame.array != 0) continue;
    ++of_array;
    // Contiguous stretches, as in the field: the node keeps a wrong cycle while the source
    // stays on that side.
    const double phase_s = std::fmod(frame.time_s, 10.0);
    if (phase_s >= 6.0) continue;
    for (std::size_t p = 0; p < 3; ++p) frame.tdoa_s[p] += phase_s < 3.0 ? kCycle_s : -kCycle_s;
    ++replaced;
  }
  ASSERT_GT(replaced, of_array / 2);
  const CalibrationResult result =
      calibrate_site(arrays, flight.frames, ReferenceTrack(flight.gps, 1.0),
                     settings_for(field_priors(), flight_settings));
  const ArrayCalibration& skewed = result.arrays[0];
  for (std::size_t i = 1; i < 4; ++i) {
    std::printf("channel %zu: delay %.1f +- %.1f us (injected %.1f)\n", i,
                skewed.channel_delay_s[i].value * 1e6, skewed.channel_delay_s[i].std * 1e6,
                skew_s[i] * 1e6);
    EXPECT_NEAR(skewed.channel_delay_s[i].value, skew_s[i], 5e-6) << "channel " << i;
  }
  EXPECT_NEAR(skewed.pitch_deg.value, 0.0, 0.5);
  EXPECT_NEAR(skewed.roll_deg.value, 0.0, 0.5);
  EXPECT_GE(result.frames_rejected, replaced);
}

// Monte Carlo: errors drawn from the priors, fresh noise each run. The reported 2-sigma interval
// must hold the truth 90-98 % of the time (95.4 % if the stds are right).
TEST(SiteCalibration, TwoSigmaCoverageOfDrawnErrors) {
  const std::vector<ArrayNominal> arrays = testing::two_arrays(0.003);
  const CalibrationPriors priors = field_priors();
  FlightSettings flight_settings;
  flight_settings.duration_s = 30.0;
  std::mt19937_64 random(2024);
  int inside = 0;
  int total = 0;
  constexpr int kRuns = 30;
  for (int run = 0; run < kRuns; ++run) {
    std::vector<InjectedErrors> errors;
    for (const auto& array : arrays) errors.push_back(testing::draw_errors(array, priors, random));
    const testing::Flight flight =
        testing::fly(arrays, errors, testing::looping_path, flight_settings, random);
    const CalibrationResult result =
        calibrate_site(arrays, flight.frames, ReferenceTrack(flight.gps, 1.0),
                       settings_for(priors, flight_settings));
    const Comparison comparison = compare(arrays, errors, result);
    for (std::size_t k = 0; k < comparison.normalised.size(); ++k) {
      const double z = comparison.normalised[k];
      inside += std::abs(z) <= 2.0;
      ++total;
    }
  }
  const double coverage = 100.0 * inside / total;
  std::printf("2-sigma coverage %.1f %% of %d estimates over %d runs\n", coverage, total, kRuns);
  EXPECT_GE(coverage, 90.0);
  EXPECT_LE(coverage, 98.0);
}

// Sources far away in the horizontal plane of the arrays: a mic offset along the vertical moves
// no pair delay, so it keeps its prior (value and std) and says so; the horizontal ones and the
// attitude are found.
TEST(SiteCalibration, AnUnexcitedMicOffsetKeepsItsPrior) {
  std::vector<ArrayNominal> arrays = testing::two_arrays(0.003);
  arrays.resize(1);
  std::vector<InjectedErrors> errors(1);
  errors[0].attitude_deg = {1.5, 0.0, 0.0};
  for (int i = 0; i < 4; ++i) {
    errors[0].mic_offsets_m.emplace_back(0.003, -0.002, 0.004);
    errors[0].channel_delay_s.push_back(0.0);
  }
  const auto centre = [&] {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& mic : testing::true_mics_site(arrays[0], errors[0])) sum += mic;
    return Eigen::Vector3d(sum / 4.0);
  }();
  const testing::Path in_plane = [&](double t) {
    const double w = 2.0 * std::numbers::pi / 40.0;
    return Eigen::Vector3d(centre.x() + 250.0 * std::cos(w * t),
                           centre.y() + 250.0 * std::sin(w * t), centre.z());
  };
  FlightSettings flight_settings;
  flight_settings.duration_s = 40.0;
  std::mt19937_64 random(11);
  const testing::Flight flight = testing::fly(arrays, errors, in_plane, flight_settings, random);
  const CalibrationResult result =
      calibrate_site(arrays, flight.frames, ReferenceTrack(flight.gps, 1.0),
                     settings_for(field_priors(), flight_settings));
  const ArrayCalibration& got = result.arrays[0];
  for (std::size_t i = 0; i < 4; ++i) {
    const Estimate& vertical = got.mic_position_m[i][2];
    std::printf("mic %zu z: %+.2f mm +- %.2f mm (prior %.2f mm) %s\n", i,
                (vertical.value - vertical.nominal) * 1e3, vertical.std * 1e3,
                vertical.prior_std * 1e3, vertical.excited ? "excited" : "unexcited");
    EXPECT_FALSE(vertical.excited) << "mic " << i;
    EXPECT_GT(vertical.std, 0.95 * vertical.prior_std) << "mic " << i;
    EXPECT_LT(std::abs(vertical.value - vertical.nominal), 0.3 * vertical.prior_std) << "mic " << i;
  }
  EXPECT_TRUE(got.yaw_deg.excited);
  EXPECT_NEAR(got.yaw_deg.value, arrays[0].yaw_deg + 1.5, 3.0 * got.yaw_deg.std);
}

TEST(SiteCalibration, RefusesAReferenceThatMissesTheFrames) {
  const std::vector<ArrayNominal> arrays = testing::two_arrays(0.003);
  std::vector<InjectedErrors> errors(2);
  for (auto& e : errors) {
    e.mic_offsets_m.assign(4, Eigen::Vector3d::Zero());
    e.channel_delay_s.assign(4, 0.0);
  }
  FlightSettings flight_settings;
  flight_settings.duration_s = 10.0;
  std::mt19937_64 random(3);
  testing::Flight flight =
      testing::fly(arrays, errors, testing::looping_path, flight_settings, random);
  for (auto& sample : flight.gps) sample.time_s += 100.0;
  try {
    calibrate_site(arrays, flight.frames, ReferenceTrack(flight.gps, 1.0),
                   settings_for(field_priors(), flight_settings));
    FAIL() << "accepted a reference 100 s after the recordings";
  } catch (const CalibrationError& error) {
    EXPECT_NE(std::string(error.what()).find("no TDOA frame falls on the reference track"),
              std::string::npos)
        << error.what();
  }
}

TEST(SiteCalibration, RefusesASourceThatNeverMoved) {
  const std::vector<ArrayNominal> arrays = testing::two_arrays(0.003);
  std::vector<InjectedErrors> errors(2);
  for (auto& e : errors) {
    e.mic_offsets_m.assign(4, Eigen::Vector3d::Zero());
    e.channel_delay_s.assign(4, 0.0);
  }
  FlightSettings flight_settings;
  flight_settings.duration_s = 10.0;
  std::mt19937_64 random(3);
  const testing::Flight flight = testing::fly(
      arrays, errors, [](double) { return Eigen::Vector3d(20.0, 30.0, 15.0); }, flight_settings,
      random);
  try {
    calibrate_site(arrays, flight.frames, ReferenceTrack(flight.gps, 1.0),
                   settings_for(field_priors(), flight_settings));
    FAIL() << "accepted a hovering source";
  } catch (const CalibrationError& error) {
    EXPECT_NE(std::string(error.what()).find("array A1: the reference is heard from 1 distinct"),
              std::string::npos)
        << error.what();
  }
}

TEST(SiteCalibration, RefusesANonFiniteTdoa) {
  const std::vector<ArrayNominal> arrays = testing::two_arrays(0.003);
  std::vector<TdoaFrame> frames(1);
  frames[0].array = 1;
  frames[0].time_s = 2.0;
  frames[0].tdoa_s = {0.0, 0.0, std::nan(""), 0.0, 0.0, 0.0};
  const ReferenceTrack reference({{0.0, {1, 2, 3}}, {10.0, {4, 5, 6}}}, 20.0);
  try {
    calibrate_site(arrays, frames, reference, CalibrationSettings{});
    FAIL() << "accepted a NaN";
  } catch (const CalibrationError& error) {
    EXPECT_STREQ(error.what(), "TDOA frame 0 (array A2, t = 2 s): a non-finite value");
  }
}

TEST(ReferenceTrack, EmissionTimeSatisfiesThePropagationDelay) {
  const ReferenceTrack track({{0.0, {0, 0, 0}}, {10.0, {100, 0, 0}}}, 20.0);
  const std::vector<Eigen::Vector3d> positions = {{0, 0, 0}, {100, 0, 0}};
  const Eigen::Vector3d listener(50.0, 200.0, 0.0);
  const auto emission = track.emission_time_s(5.0, listener, 343.0, positions);
  ASSERT_TRUE(emission);
  const Eigen::Vector3d source(10.0 * *emission, 0.0, 0.0);
  EXPECT_NEAR(*emission + (source - listener).norm() / 343.0, 5.0, 1e-9);
  EXPECT_LT(*emission, 5.0 - 199.0 / 343.0);
  EXPECT_FALSE(track.emission_time_s(0.1, listener, 343.0, positions));  // before the track
  const ReferenceTrack gappy({{0.0, {0, 0, 0}}, {10.0, {100, 0, 0}}}, 5.0);
  EXPECT_FALSE(gappy.bracket(5.0));
}

}  // namespace
}  // namespace dronetrack::calib

namespace dronetrack::calib {
namespace {

// Levels of four channels over 60 one-second stretches: a flight's level swinging by 20 dB, each
// channel's gain on top, 0.3 dB of scatter (the spreading across the array, noise), a stretch
// where channel 2 went silent. The gains come back relative to their mean, within their std.
TEST(ChannelGains, LevelsGiveTheGainsRelativeToTheirMean) {
  const std::vector<double> gains_db = {0.9, -0.4, 1.3, -1.1};
  double mean_gain = 0.0;
  for (double gain : gains_db) mean_gain += gain / 4.0;
  std::mt19937_64 random(21);
  std::normal_distribution<double> scatter(0.0, 0.3);
  std::vector<std::vector<double>> levels;
  for (int k = 0; k < 60; ++k) {
    const double flight_db = -40.0 + 10.0 * std::sin(0.2 * k);
    std::vector<double> stretch;
    for (double gain : gains_db) stretch.push_back(flight_db + gain + scatter(random));
    levels.push_back(stretch);
  }
  levels[17][2] = -120.0;  // silent: left out
  const std::vector<Estimate> found = estimate_channel_gains(levels);
  ASSERT_EQ(found.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    std::printf("channel %zu gain %+.3f +- %.3f dB (drawn %+.3f relative to the mean)\n", i,
                found[i].value, found[i].std, gains_db[i] - mean_gain);
    EXPECT_NEAR(found[i].value, gains_db[i] - mean_gain, 3.0 * found[i].std);
    EXPECT_LT(found[i].std, 0.1);
  }
  EXPECT_TRUE(estimate_channel_gains({{-40, -41}, {-40, -41}}).empty());  // too few stretches
}

}  // namespace
}  // namespace dronetrack::calib
