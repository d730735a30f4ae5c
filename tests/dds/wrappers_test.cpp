// The RAII wrappers and QoS over a real (loopback) DDS domain: every topic type makes the round
// trip core struct -> IDL -> wire -> IDL -> core struct intact, loans are returned, a burst larger
// than one take is taken entirely, a late joiner gets the current tracks at once, and a vanished
// writer leaves its instance NOT_ALIVE_NO_WRITERS.
#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <optional>

#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"
#include "tests/dds/dds_test_support.hpp"

namespace dronetrack::dds::wrappers_test {
namespace {

using namespace std::chrono_literals;

// Waits for the first valid sample and converts it while the loan is held.
template <class T, class Convert>
bool receive_one(const Reader<T>& reader, Convert convert, std::chrono::nanoseconds timeout = 5s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    reader.wait(100ms);
    Samples<T> samples = reader.take();
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (samples.info(i).valid_data) {
        convert(samples.data(i));
        return true;
      }
    }
  }
  return false;
}

class DdsWrappers : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { testing::use_loopback(); }
};

TEST_F(DdsWrappers, DoaRoundTripKeepsEveryField) {
  Participant participant(111);
  Topic<dronetrack_Doa> topic(participant);
  Qos writer_qos, reader_qos;
  doa_writer_qos(writer_qos);
  doa_reader_qos(reader_qos);
  Writer<dronetrack_Doa> writer(participant, topic, writer_qos);
  Reader<dronetrack_Doa> reader(participant, topic, reader_qos);
  ASSERT_TRUE(writer.wait_for_readers(1, 5s));

  doa::DoaMeasurement sent;
  sent.array_id = "N2";
  sent.time_s = 12.3456789;
  sent.direction = Eigen::Vector3d(1.0, 2.0, 0.5).normalized();
  sent.azel_covariance_rad2 << 4e-4, 1e-5, 1e-5, 9e-4;
  sent.quality = 0.75;
  sent.snr_db = 17.5;
  sent.source_index = 1;
  sent.ambiguity = doa::DoaAmbiguity::mirror_up_down;
  sent.pair_count = 6;
  for (int i = 0; i < 6; ++i) sent.tdoa_s[static_cast<std::size_t>(i)] = (i - 2.5) * 1e-4;
  dronetrack_Doa sample{};
  to_idl(sent, 0, sample);
  writer.write(sample);

  const std::vector<std::string> ids{"N1", "N2", "N3"};
  doa::DoaMeasurement got;
  SampleProblem problem = SampleProblem::bad_value;
  ASSERT_TRUE(
      receive_one(reader, [&](const dronetrack_Doa& s) { problem = from_idl(s, ids, got); }));
  ASSERT_EQ(problem, SampleProblem::none);
  EXPECT_EQ(got.array_id, "N2");
  EXPECT_EQ(got.array_index, 1);
  EXPECT_NEAR(got.time_s, sent.time_s, 1e-9);
  EXPECT_NEAR((got.direction - sent.direction).norm(), 0.0, 1e-12);
  EXPECT_EQ(got.azel_covariance_rad2, sent.azel_covariance_rad2);
  EXPECT_EQ(got.quality, sent.quality);
  EXPECT_EQ(got.snr_db, sent.snr_db);
  EXPECT_EQ(got.source_index, 1);
  EXPECT_EQ(got.ambiguity, doa::DoaAmbiguity::mirror_up_down);
  EXPECT_EQ(got.pair_count, 6);
  EXPECT_EQ(got.tdoa_s, sent.tdoa_s);
}

TEST_F(DdsWrappers, LiveTimeOffsetIsAddedInNanoseconds) {
  // A live node adds its stream's Unix start time; the round trip must keep microseconds.
  doa::DoaMeasurement measurement;
  measurement.array_id = "N1";
  measurement.time_s = 0.123456;
  dronetrack_Doa sample{};
  const std::int64_t start_ns = 1'763'700'000'000'000'000;
  to_idl(measurement, start_ns, sample);
  EXPECT_EQ(sample.time_ns, start_ns + 123'456'000);
  doa::DoaMeasurement back;
  ASSERT_EQ(from_idl(sample, {"N1"}, back), SampleProblem::none);
  EXPECT_NEAR(back.time_s - 1'763'700'000.0, 0.123456, 1e-6);
}

TEST_F(DdsWrappers, NodeStatusTrackAndAlertRoundTrip) {
  Participant participant(112);
  Topic<dronetrack_NodeStatus> status_topic(participant);
  Topic<dronetrack_Track> track_topic(participant);
  Topic<dronetrack_Alert> alert_topic(participant);
  Qos sw, sr, tw, tr, aw, ar;
  status_writer_qos(sw);
  status_reader_qos(sr);
  track_writer_qos(tw);
  track_reader_qos(tr);
  alert_writer_qos(aw);
  alert_reader_qos(ar);
  Writer<dronetrack_NodeStatus> status_writer(participant, status_topic, sw);
  Reader<dronetrack_NodeStatus> status_reader(participant, status_topic, sr);
  Writer<dronetrack_Track> track_writer(participant, track_topic, tw);
  Reader<dronetrack_Track> track_reader(participant, track_topic, tr);
  Writer<dronetrack_Alert> alert_writer(participant, alert_topic, aw);
  Reader<dronetrack_Alert> alert_reader(participant, alert_topic, ar);
  ASSERT_TRUE(alert_writer.wait_for_readers(1, 5s));

  doa::NodeStatus status;
  status.array_id = "N3";
  status.sample_rate_hz = 48000.0;
  status.overruns = 3;
  status.clipped_samples = 14;
  status.non_finite_samples = 2;
  status.level_dbfs = -31.5;
  status.noise_floor_dbfs = -60.25;
  status.snr_db = 12.0;
  status.detecting = true;
  status.software_version = "dronetrack 0.1.0";
  status.incident_clips = 4;
  status.incident_write_errors = 1;
  status.channels = {{0, 0, 0, 0, -31.0},
                     {doa::health_flag(doa::HealthProblem::silent),
                      doa::health_flag(doa::HealthProblem::silent), 0, 14, -120.0}};
  dronetrack_NodeStatus status_sample{};
  to_idl(status, 5'000'000'000, status_sample);
  status_writer.write(status_sample);

  fusion::TrackReport track;
  track.id = 7;
  track.time_s = 9.5;
  track.position_m = {10.0, -20.0, 30.0};
  track.velocity_mps = {1.0, 2.0, -0.5};
  track.acceleration_mps2 = {0.1, 0.0, -0.2};
  for (int r = 0; r < 9; ++r) {
    for (int c = 0; c < 9; ++c) track.covariance(r, c) = (r == c) ? 1.0 + r : 0.01 * (r + c);
  }
  track.status = fusion::TrackStatus::coasting;
  track.contributing_arrays = 0b1011;
  track.last_update_s = 9.25;
  dronetrack_Track track_sample{};
  to_idl(track, track_sample);
  track_writer.write(track_sample);

  fusion::ZoneEvent event{"inner-yard", 7, false, 9.5, Eigen::Vector3d(1.0, 2.0, 3.0)};
  dronetrack_Alert alert_sample{};
  to_idl(event, alert_sample);
  alert_writer.write(alert_sample);

  doa::NodeStatus got_status;
  ASSERT_TRUE(receive_one(status_reader, [&](const dronetrack_NodeStatus& s) {
    EXPECT_EQ(from_idl(s, {"N1", "N3"}, got_status), SampleProblem::none);
  }));
  EXPECT_EQ(got_status.array_id, "N3");
  EXPECT_EQ(got_status.time_s, 5.0);
  EXPECT_EQ(got_status.overruns, 3);
  EXPECT_EQ(got_status.clipped_samples, 14);
  EXPECT_EQ(got_status.non_finite_samples, 2);
  EXPECT_EQ(got_status.noise_floor_dbfs, -60.25);
  EXPECT_TRUE(got_status.detecting);
  EXPECT_EQ(got_status.software_version, "dronetrack 0.1.0");
  EXPECT_EQ(got_status.incident_clips, 4);
  EXPECT_EQ(got_status.incident_write_errors, 1);
  ASSERT_EQ(got_status.channels.size(), 2U);
  EXPECT_EQ(got_status.channels[1].problems, doa::health_flag(doa::HealthProblem::silent));
  EXPECT_EQ(got_status.channels[1].clipped_samples, 14);
  EXPECT_EQ(got_status.channels[0].rms_dbfs, -31.0);

  fusion::TrackReport got_track;
  ASSERT_TRUE(receive_one(track_reader, [&](const dronetrack_Track& s) {
    EXPECT_EQ(from_idl(s, got_track), SampleProblem::none);
  }));
  EXPECT_EQ(got_track.id, 7);
  EXPECT_EQ(got_track.time_s, 9.5);
  EXPECT_EQ(got_track.position_m, track.position_m);
  EXPECT_EQ(got_track.velocity_mps, track.velocity_mps);
  EXPECT_EQ(got_track.acceleration_mps2, track.acceleration_mps2);
  EXPECT_EQ(got_track.covariance, track.covariance);  // symmetric: the upper triangle suffices
  EXPECT_EQ(got_track.status, fusion::TrackStatus::coasting);
  EXPECT_EQ(got_track.contributing_arrays, 0b1011u);
  EXPECT_EQ(got_track.last_update_s, 9.25);

  fusion::ZoneEvent got_event;
  ASSERT_TRUE(receive_one(alert_reader, [&](const dronetrack_Alert& s) {
    EXPECT_EQ(from_idl(s, got_event), SampleProblem::none);
  }));
  EXPECT_EQ(got_event.zone, "inner-yard");
  EXPECT_EQ(got_event.track_id, 7);
  EXPECT_FALSE(got_event.entered);
  EXPECT_EQ(got_event.position_m, event.position_m);
}

TEST_F(DdsWrappers, BurstLargerThanOneLoanIsTakenEntirely) {
  // 300 instances (Alert is keyed by zone + track) are more than one take of 64: the
  // ReadCondition keeps the waitset triggered until the last one is taken.
  Participant participant(113);
  Topic<dronetrack_Alert> topic(participant);
  Qos wq, rq;
  alert_writer_qos(wq);
  alert_reader_qos(rq);
  Writer<dronetrack_Alert> writer(participant, topic, wq);
  Reader<dronetrack_Alert> reader(participant, topic, rq);
  ASSERT_TRUE(writer.wait_for_readers(1, 5s));
  constexpr int kCount = 300;
  for (int id = 0; id < kCount; ++id) {
    dronetrack_Alert sample{};
    to_idl(fusion::ZoneEvent{"z", id, true, id * 0.1, Eigen::Vector3d::Zero()}, sample);
    writer.write(sample);
  }
  std::map<int, int> seen;
  int takes = 0;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (seen.size() < kCount && std::chrono::steady_clock::now() < deadline) {
    if (!reader.wait(1s)) continue;
    Samples<dronetrack_Alert> samples = reader.take();
    ++takes;
    EXPECT_LE(samples.size(), static_cast<std::size_t>(Samples<dronetrack_Alert>::kMaxSamples));
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (samples.info(i).valid_data) ++seen[samples.data(i).track_id];
    }
  }
  EXPECT_EQ(seen.size(), static_cast<std::size_t>(kCount));
  for (const auto& [id, count] : seen) EXPECT_EQ(count, 1) << "track " << id;
  EXPECT_GE(takes, kCount / Samples<dronetrack_Alert>::kMaxSamples);
  // Every loan was returned: the reader is empty, and taking on an empty reader lends nothing.
  EXPECT_FALSE(reader.wait(50ms));
  EXPECT_TRUE(reader.take().empty());
}

TEST_F(DdsWrappers, WriterRejectsOversizedSequence) {
  Participant participant(114);
  Topic<dronetrack_Doa> topic(participant);
  Qos wq;
  doa_writer_qos(wq);
  Writer<dronetrack_Doa> writer(participant, topic, wq);
  std::array<double, 40> tdoas{};
  dronetrack_Doa sample{};
  copy_bounded(sample.array_id, "N1");
  sample.direction[0] = 1.0;
  sample.tdoa_s = {40, 40, tdoas.data(), false};
  EXPECT_EQ(writer.try_write(sample), DDS_RETCODE_BAD_PARAMETER);
  EXPECT_THROW(writer.write(sample), DdsError);
}

TEST_F(DdsWrappers, LateJoinerGetsCurrentTracksAtOnce) {
  Participant participant(115);
  Topic<dronetrack_Track> topic(participant);
  Qos wq, rq;
  track_writer_qos(wq);
  track_reader_qos(rq);
  Writer<dronetrack_Track> writer(participant, topic, wq);
  // Three tracks, several updates each; track 2 ends (disposed) before the reader exists.
  for (int tick = 0; tick < 5; ++tick) {
    for (int id = 1; id <= 3; ++id) {
      fusion::TrackReport report;
      report.id = id;
      report.time_s = tick * 0.1;
      report.position_m = {id * 10.0, tick * 1.0, 50.0};
      dronetrack_Track sample{};
      to_idl(report, sample);
      writer.write(sample);
    }
  }
  dronetrack_Track ended{};
  ended.id = 2;
  writer.dispose(ended);

  const auto joined = std::chrono::steady_clock::now();
  Reader<dronetrack_Track> late(participant, topic, rq);
  std::map<int, fusion::TrackReport> current;
  while (current.size() < 2 && std::chrono::steady_clock::now() - joined < 2s) {
    late.wait(100ms);
    Samples<dronetrack_Track> samples = late.take();
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (!samples.info(i).valid_data) continue;
      fusion::TrackReport report;
      ASSERT_EQ(from_idl(samples.data(i), report), SampleProblem::none);
      current[report.id] = report;
    }
  }
  const auto waited = std::chrono::steady_clock::now() - joined;
  ASSERT_EQ(current.size(), 2u);
  EXPECT_TRUE(current.count(1) && current.count(3)) << "the disposed track 2 must not come back";
  // Only the newest state per track is kept for late joiners.
  EXPECT_EQ(current[1].time_s, 0.4);
  EXPECT_EQ(current[3].position_m.y(), 4.0);
  EXPECT_LT(waited, 1s) << "late joiner waited " << std::chrono::duration<double>(waited).count()
                        << " s";
}

TEST_F(DdsWrappers, VanishedWriterLeavesInstanceWithoutWriters) {
  // The fusion learns which array died from the NodeStatus instance state.
  Participant participant(116);
  Topic<dronetrack_NodeStatus> topic(participant);
  Qos wq, rq;
  status_writer_qos(wq);
  status_reader_qos(rq);
  Reader<dronetrack_NodeStatus> reader(participant, topic, rq, kLivelinessStatus);
  std::optional<Writer<dronetrack_NodeStatus>> writer;
  writer.emplace(participant, topic, wq);
  ASSERT_TRUE(writer->wait_for_readers(1, 5s));
  dronetrack_NodeStatus sample{};
  doa::NodeStatus status;
  status.array_id = "N4";
  to_idl(status, 0, sample);
  writer->write(sample);
  ASSERT_TRUE(receive_one(reader, [](const dronetrack_NodeStatus&) {}));
  writer.reset();  // a graceful end; a killed process ends the same way after the lease

  bool gone = false;
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!gone && std::chrono::steady_clock::now() < deadline) {
    reader.wait(100ms);
    Samples<dronetrack_NodeStatus> samples = reader.take();
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (samples.info(i).instance_state == DDS_NOT_ALIVE_NO_WRITERS_INSTANCE_STATE) {
        EXPECT_STREQ(samples.data(i).array_id, "N4");
        gone = true;
      }
    }
  }
  EXPECT_TRUE(gone);
  EXPECT_EQ(reader.matched_writers(), 0u);
}

}  // namespace
}  // namespace dronetrack::dds::wrappers_test
