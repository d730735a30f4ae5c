// Incoming samples are validated field by field: each kind of damage is named, nothing throws.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "dds_idl/conversions.hpp"

namespace dronetrack::dds::conversions_test {
namespace {

const std::vector<std::string> kArrays{"N1", "N2"};

dronetrack_Doa valid_doa(std::array<double, doa::kMaxPairs>& tdoas) {
  doa::DoaMeasurement measurement;
  measurement.array_id = "N1";
  measurement.time_s = 3.0;
  measurement.direction = Eigen::Vector3d(0.0, 0.6, 0.8);
  measurement.pair_count = 6;
  measurement.tdoa_s[0] = 1e-4;
  dronetrack_Doa sample{};
  to_idl(measurement, 0, sample);
  tdoas = measurement.tdoa_s;
  sample.tdoa_s._buffer = tdoas.data();  // outlive `measurement`
  return sample;
}

TEST(DdsConversions, ValidDoaIsAccepted) {
  std::array<double, doa::kMaxPairs> tdoas{};
  const dronetrack_Doa sample = valid_doa(tdoas);
  doa::DoaMeasurement out;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::none);
  EXPECT_EQ(out.array_index, 0);
  EXPECT_NEAR(out.azel_covariance_rad2(0, 0), 1e-4, 1e-18);
}

TEST(DdsConversions, EachKindOfDamagedDoaIsNamed) {
  std::array<double, doa::kMaxPairs> tdoas{};
  std::array<double, 64> long_tdoas{};
  struct Case {
    const char* what;
    void (*damage)(dronetrack_Doa&, std::array<double, 64>&);
    SampleProblem expected;
  };
  const Case cases[] = {
      {"empty key", [](dronetrack_Doa& s, auto&) { s.array_id[0] = '\0'; },
       SampleProblem::empty_key},
      {"unknown array", [](dronetrack_Doa& s, auto&) { copy_bounded(s.array_id, "X9"); },
       SampleProblem::unknown_array},
      {"unterminated key", [](dronetrack_Doa& s, auto&) { std::memset(s.array_id, 'A', 65); },
       SampleProblem::unknown_array},
      {"NaN direction",
       [](dronetrack_Doa& s, auto&) { s.direction[1] = std::numeric_limits<double>::quiet_NaN(); },
       SampleProblem::non_finite},
      {"Inf quality",
       [](dronetrack_Doa& s, auto&) { s.quality = std::numeric_limits<double>::infinity(); },
       SampleProblem::non_finite},
      {"NaN covariance",
       [](dronetrack_Doa& s, auto&) {
         s.azel_covariance_rad2[2] = std::numeric_limits<double>::quiet_NaN();
       },
       SampleProblem::non_finite},
      {"negative time", [](dronetrack_Doa& s, auto&) { s.time_ns = -5; },
       SampleProblem::absurd_time},
      // Seconds this far out no longer convert back to int64 nanoseconds (fuzz/dds_conversions).
      {"time beyond the round trip",
       [](dronetrack_Doa& s, auto&) { s.time_ns = std::numeric_limits<std::int64_t>::max(); },
       SampleProblem::absurd_time},
      {"too many TDOAs",
       [](dronetrack_Doa& s, std::array<double, 64>& storage) {
         s.tdoa_s = {64, 64, storage.data(), false};
       },
       SampleProblem::oversized_sequence},
      {"length without buffer",
       [](dronetrack_Doa& s, auto&) {
         s.tdoa_s = {3, 3, nullptr, false};
       },
       SampleProblem::oversized_sequence},
      {"not a unit vector", [](dronetrack_Doa& s, auto&) { s.direction[0] = 0.5; },
       SampleProblem::bad_value},
      {"zero variance", [](dronetrack_Doa& s, auto&) { s.azel_covariance_rad2[0] = 0.0; },
       SampleProblem::bad_value},
      {"covariance not positive definite",
       [](dronetrack_Doa& s, auto&) { s.azel_covariance_rad2[1] = 1.0; }, SampleProblem::bad_value},
      {"ambiguity out of range", [](dronetrack_Doa& s, auto&) { s.ambiguity = 7; },
       SampleProblem::bad_value},
      {"negative source index", [](dronetrack_Doa& s, auto&) { s.source_index = -1; },
       SampleProblem::bad_value},
  };
  for (const Case& test_case : cases) {
    dronetrack_Doa sample = valid_doa(tdoas);
    test_case.damage(sample, long_tdoas);
    doa::DoaMeasurement out;
    EXPECT_EQ(from_idl(sample, kArrays, out), test_case.expected)
        << test_case.what << ": got " << to_string(from_idl(sample, kArrays, out));
  }
}

// A moving two-mic array's DOA: pose stamp, cone and peaks cross the wire and are validated.
TEST(DdsConversions, ConeAndPoseRoundTripAndAreValidated) {
  doa::DoaMeasurement measurement;
  measurement.array_id = "N2";
  measurement.time_s = 2.0;
  measurement.ambiguity = doa::DoaAmbiguity::cone;
  measurement.ambiguity_axis = Eigen::Vector3d(0.0, 1.0, 0.0);
  measurement.cone_angle_rad = 0.7;
  measurement.cone_angle_variance_rad2 = 1e-3;
  measurement.cone_peak_count = 2;
  measurement.cone_peak_angle_rad = {0.7, 2.0, 0.0, 0.0};
  measurement.cone_peak_weight = {0.8, 0.3, 0.0, 0.0};
  measurement.pose = {Eigen::Vector3d(5.0, 6.0, -7.0),
                      Eigen::Quaterniond(doa::attitude_to_site(-120.0, 2.0, 1.0)), true};
  dronetrack_Doa sample{};
  to_idl(measurement, 0, sample);
  doa::DoaMeasurement out;
  ASSERT_EQ(from_idl(sample, kArrays, out), SampleProblem::none);
  EXPECT_TRUE(out.pose.moving);
  EXPECT_LT((out.pose.centre_m - measurement.pose.centre_m).norm(), 1e-12);
  EXPECT_LT(out.pose.array_to_site.angularDistance(measurement.pose.array_to_site), 1e-12);
  EXPECT_EQ(out.ambiguity, doa::DoaAmbiguity::cone);
  EXPECT_DOUBLE_EQ(out.cone_angle_rad, 0.7);
  EXPECT_DOUBLE_EQ(out.cone_angle_variance_rad2, 1e-3);
  ASSERT_EQ(out.cone_peak_count, 2);
  EXPECT_DOUBLE_EQ(out.cone_peak_angle_rad[1], 2.0);
  EXPECT_DOUBLE_EQ(out.cone_peak_weight[1], 0.3);

  struct Case {
    const char* what;
    void (*damage)(dronetrack_Doa&);
    SampleProblem expected;
  };
  const Case cases[] = {
      {"NaN pose",
       [](dronetrack_Doa& s) { s.array_centre_m[2] = std::numeric_limits<double>::quiet_NaN(); },
       SampleProblem::non_finite},
      {"not a unit quaternion", [](dronetrack_Doa& s) { s.array_orientation[0] = 3.0; },
       SampleProblem::bad_value},
      {"pose 1000 km away", [](dronetrack_Doa& s) { s.array_centre_m[0] = 1e6; },
       SampleProblem::bad_value},
      {"axis not unit", [](dronetrack_Doa& s) { s.ambiguity_axis[1] = 0.5; },
       SampleProblem::bad_value},
      {"cone angle beyond pi", [](dronetrack_Doa& s) { s.cone_angle_rad = 4.0; },
       SampleProblem::bad_value},
      {"zero cone variance", [](dronetrack_Doa& s) { s.cone_angle_variance_rad2 = 0.0; },
       SampleProblem::bad_value},
      {"peak sequences of different lengths",
       [](dronetrack_Doa& s) { s.cone_peak_weight._length = 1; },
       SampleProblem::oversized_sequence},
      {"negative peak weight", [](dronetrack_Doa& s) { s.cone_peak_weight._buffer[0] = -1.0; },
       SampleProblem::bad_value},
      {"peaks on a full-direction DOA", [](dronetrack_Doa& s) { s.ambiguity = 0; },
       SampleProblem::bad_value},
  };
  for (const Case& test_case : cases) {
    doa::DoaMeasurement copy = measurement;
    dronetrack_Doa damaged{};
    to_idl(copy, 0, damaged);
    test_case.damage(damaged);
    EXPECT_EQ(from_idl(damaged, kArrays, out), test_case.expected)
        << test_case.what << ": got " << to_string(from_idl(damaged, kArrays, out));
  }
}

TEST(DdsConversions, ArrayPoseRoundTripAndIsValidated) {
  const doa::PoseSample pose{12.5, Eigen::Vector3d(100.0, -50.0, -3.0), 170.0, -4.0, 2.0};
  dronetrack_ArrayPose sample{};
  to_idl("H1", pose, 0, sample);
  doa::PoseSample out;
  ASSERT_EQ(from_idl(sample, "H1", out), SampleProblem::none);
  EXPECT_DOUBLE_EQ(out.time_s, 12.5);
  EXPECT_EQ(out.position_m, pose.position_m);
  EXPECT_DOUBLE_EQ(out.yaw_deg, 170.0);
  EXPECT_EQ(from_idl(sample, "H2", out), SampleProblem::unknown_array);
  dronetrack_ArrayPose damaged = sample;
  damaged.yaw_deg = std::numeric_limits<double>::infinity();
  EXPECT_EQ(from_idl(damaged, "H1", out), SampleProblem::non_finite);
  damaged = sample;
  damaged.pitch_deg = 120.0;
  EXPECT_EQ(from_idl(damaged, "H1", out), SampleProblem::bad_value);
  damaged = sample;
  damaged.time_ns = -1;
  EXPECT_EQ(from_idl(damaged, "H1", out), SampleProblem::absurd_time);
  damaged = sample;
  damaged.array_id[0] = '\0';
  EXPECT_EQ(from_idl(damaged, "H1", out), SampleProblem::empty_key);
}

TEST(DdsConversions, NaNTdoaInsideTheSequenceIsCaught) {
  std::array<double, doa::kMaxPairs> tdoas{};
  dronetrack_Doa sample = valid_doa(tdoas);
  tdoas[5] = std::numeric_limits<double>::quiet_NaN();
  doa::DoaMeasurement out;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::non_finite);
}

TEST(DdsConversions, DamagedStatusTrackAndAlert) {
  dronetrack_NodeStatus status{};
  copy_bounded(status.array_id, "N2");
  doa::NodeStatus status_out;
  EXPECT_EQ(from_idl(status, kArrays, status_out), SampleProblem::none);
  status.level_dbfs = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(from_idl(status, kArrays, status_out), SampleProblem::non_finite);
  status.level_dbfs = 0.0;
  status.overruns = -1;
  EXPECT_EQ(from_idl(status, kArrays, status_out), SampleProblem::bad_value);
  status.overruns = 0;
  status.incident_write_errors = -1;
  EXPECT_EQ(from_idl(status, kArrays, status_out), SampleProblem::bad_value);
  status.incident_write_errors = 0;
  status.incident_clips = -1;
  EXPECT_EQ(from_idl(status, kArrays, status_out), SampleProblem::bad_value);
  status.array_id[0] = '\0';
  EXPECT_EQ(from_idl(status, kArrays, status_out), SampleProblem::empty_key);

  dronetrack_Track track{};
  fusion::TrackReport track_out;
  EXPECT_EQ(from_idl(track, track_out), SampleProblem::none);
  track.covariance_upper[44] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(from_idl(track, track_out), SampleProblem::non_finite);
  track.covariance_upper[44] = 1.0;
  track.status = 9;
  EXPECT_EQ(from_idl(track, track_out), SampleProblem::bad_value);
  track.status = 0;
  track.one_array = true;
  track.hypotheses = 12;
  ASSERT_EQ(from_idl(track, track_out), SampleProblem::none);
  EXPECT_TRUE(track_out.one_array);
  EXPECT_EQ(track_out.hypotheses, 12);
  track.hypotheses = -1;
  EXPECT_EQ(from_idl(track, track_out), SampleProblem::bad_value);

  dronetrack_Alert alert{};
  fusion::ZoneEvent alert_out;
  EXPECT_EQ(from_idl(alert, alert_out), SampleProblem::empty_key);
  copy_bounded(alert.zone, "yard");
  EXPECT_EQ(from_idl(alert, alert_out), SampleProblem::none);
}

// Per-channel audio health: round trip, then what a remote node could get wrong.
TEST(DdsConversions, NodeStatusChannelsRoundTripAndAreValidated) {
  doa::NodeStatus status;
  status.array_id = "N2";
  status.channels = {{0, 0, 0, 0, -31.5},
                     {doa::health_flag(doa::HealthProblem::non_finite),
                      doa::health_flag(doa::HealthProblem::non_finite) |
                          doa::health_flag(doa::HealthProblem::clipped),
                      48000, 12, -120.0},
                     {0, doa::health_flag(doa::HealthProblem::absurd_level), 0, 9, -20.0}};
  dronetrack_NodeStatus sample{};
  to_idl(status, 0, sample);
  EXPECT_EQ(sample.channel_count, 3);
  EXPECT_EQ(sample.channels[1].non_finite_samples, 48000);
  doa::NodeStatus out;
  ASSERT_EQ(from_idl(sample, kArrays, out), SampleProblem::none);
  ASSERT_EQ(out.channels.size(), 3U);
  for (std::size_t c = 0; c < 3; ++c) {
    EXPECT_EQ(out.channels[c].problems, status.channels[c].problems) << c;
    EXPECT_EQ(out.channels[c].problems_seen, status.channels[c].problems_seen) << c;
    EXPECT_EQ(out.channels[c].non_finite_samples, status.channels[c].non_finite_samples) << c;
    EXPECT_EQ(out.channels[c].clipped_samples, status.channels[c].clipped_samples) << c;
    EXPECT_EQ(out.channels[c].rms_dbfs, status.channels[c].rms_dbfs) << c;
  }

  sample.channels[2].rms_dbfs = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::non_finite);
  sample.channels[2].rms_dbfs = -20.0;
  sample.channels[1].problems = 0x80;  // no such problem
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::bad_value);
  sample.channels[1].problems = 0;
  sample.channels[0].clipped_samples = -1;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::bad_value);
  sample.channels[0].clipped_samples = 0;
  sample.channel_count = 9;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::bad_value);
  sample.channel_count = 0;
  ASSERT_EQ(from_idl(sample, kArrays, out), SampleProblem::none);
  EXPECT_TRUE(out.channels.empty());
}

// The channels judged against each other (issue 16): flags, offsets and the array's residuals
// round-trip; NaN, unknown bits and values out of bounds are refused.
TEST(DdsConversions, NodeStatusArrayHealthRoundTripsAndIsValidated) {
  doa::NodeStatus status;
  status.array_id = "N2";
  status.closure_residual_us = 12.5;
  status.fit_residual_us = 3.25;
  status.channels = {
      {0, 0, 0, 0, -31.5, 0, 0, 0.25, -1.5},
      {0, 0, 0, 0, -31.0, doa::array_flag(doa::ArrayProblem::polarity_flipped),
       doa::array_flag(doa::ArrayProblem::polarity_flipped) |
           doa::array_flag(doa::ArrayProblem::skew) | doa::array_flag(doa::ArrayProblem::swapped),
       6.0, 200.0, 12.5}};
  dronetrack_NodeStatus sample{};
  to_idl(status, 0, sample);
  doa::NodeStatus out;
  ASSERT_EQ(from_idl(sample, kArrays, out), SampleProblem::none);
  EXPECT_EQ(out.closure_residual_us, 12.5);
  EXPECT_EQ(out.fit_residual_us, 3.25);
  ASSERT_EQ(out.channels.size(), 2U);
  EXPECT_EQ(out.channels[1].array_problems, status.channels[1].array_problems);
  EXPECT_EQ(out.channels[1].array_problems_seen, status.channels[1].array_problems_seen);
  EXPECT_EQ(out.channels[1].level_offset_db, 6.0);
  EXPECT_EQ(out.channels[1].delay_offset_us, 200.0);
  EXPECT_EQ(out.channels[1].delay_std_us, 12.5);
  EXPECT_EQ(out.channels[0].delay_std_us, doa::kMaxHealthDelay_us);  // not judged
  EXPECT_EQ(out.channels[0].level_offset_db, 0.25);

  const double nan = std::numeric_limits<double>::quiet_NaN();
  sample.channels[1].level_offset_db = nan;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::non_finite);
  sample.channels[1].level_offset_db = 301.0;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::bad_value);
  sample.channels[1].level_offset_db = 6.0;
  sample.channels[0].delay_offset_us = nan;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::non_finite);
  sample.channels[0].delay_offset_us = 0.0;
  sample.channels[0].delay_std_us = -1.0;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::bad_value);
  sample.channels[0].delay_std_us = 5.0;
  sample.channels[0].array_problems_seen = 0x40;  // no such check
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::bad_value);
  sample.channels[0].array_problems_seen = 0;
  sample.closure_residual_us = nan;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::non_finite);
  sample.closure_residual_us = -1.0;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::bad_value);
  sample.closure_residual_us = 0.0;
  sample.fit_residual_us = 2e6;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::bad_value);
  sample.fit_residual_us = 0.0;
  EXPECT_EQ(from_idl(sample, kArrays, out), SampleProblem::none);
}

TEST(DdsConversions, LongIdsAreTruncatedToTheirBound) {
  dronetrack_NodeStatus status{};
  copy_bounded(status.software_version, std::string(100, 'v'));
  EXPECT_EQ(std::strlen(status.software_version), 32u);
}

}  // namespace
}  // namespace dronetrack::dds::conversions_test
