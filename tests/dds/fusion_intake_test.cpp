// The fusion process's DDS intake under attack: a clean stream of DOAs toward a hovering drone is
// published together with malformed samples (NaN, Inf, absurd times, unknown and empty array
// ids, non-unit directions, bad covariances, bad enums) and a seeded random fuzz in which every
// sample carries at least one defect. The fusion must survive, count each kind, ignore every bad
// sample, and still track the drone from the clean stream alone.
//
// Oversized TDOA sequences cannot be sent through Cyclone at all (dds_write refuses them with
// BAD_PARAMETER: DdsWrappers.WriterRejectsOversizedSequence); the receiving check is covered by
// DdsConversions.EachKindOfDamagedDoaIsNamed.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <utility>

#include <nlohmann/json.hpp>

#include "apps/dds_fusion_service.hpp"
#include "apps/metrics.hpp"
#include "config/site_config.hpp"
#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"
#include "tests/dds/dds_test_support.hpp"
#include "tests/http_api/exposition_checker.hpp"

namespace dronetrack::apps {
namespace {

using namespace std::chrono_literals;
using dds::SampleProblem;

constexpr const char* kSite = R"({
  "speed_of_sound_mps": 343.0,
  "arrays": [
    {"id": "N1", "position_m": [-60, -60, 2], "yaw_deg": 0,
     "mics_m": [[0,0,0.5],[0.4714,0,-0.1667],[-0.2357,0.4082,-0.1667],[-0.2357,-0.4082,-0.1667]]},
    {"id": "N2", "position_m": [60, -60, 2], "yaw_deg": 0,
     "mics_m": [[0,0,0.5],[0.4714,0,-0.1667],[-0.2357,0.4082,-0.1667],[-0.2357,-0.4082,-0.1667]]},
    {"id": "N3", "position_m": [0, 60, 2], "yaw_deg": 0,
     "mics_m": [[0,0,0.5],[0.4714,0,-0.1667],[-0.2357,0.4082,-0.1667],[-0.2357,-0.4082,-0.1667]]}
  ]
})";

class LastTracks : public FusionObserver {
 public:
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) override {
    time_s_ = time_s;
    tracks_ = tracks;
  }
  double time_s_ = 0.0;
  std::vector<fusion::TrackReport> tracks_;
};

TEST(DdsFusionIntake, MalformedSamplesAreCountedAndIgnoredAndTrackingGoesOn) {
  dds::testing::use_loopback();
  std::vector<std::string> warnings;
  config::LoadOptions load_options;
  load_options.check_recordings = false;
  const config::SiteConfig site = config::parse_site_config(kSite, ".", warnings, load_options);
  const Eigen::Vector3d drone_m(10.0, 20.0, 30.0);

  dds::Participant participant(121);
  LastTracks last;
  FusionMetrics metrics("fusion", array_ids(site));  // what /metrics would say of this run
  DdsFusionService service(site, participant, {&last, &metrics});
  dds::Topic<dronetrack_Doa> doa_topic(participant);
  dds::Topic<dronetrack_NodeStatus> status_topic(participant);
  dds::Qos doa_qos, status_qos;
  dds::doa_writer_qos(doa_qos);
  dds::status_writer_qos(status_qos);
  dds::Writer<dronetrack_Doa> doa_writer(participant, doa_topic, doa_qos);
  dds::Writer<dronetrack_NodeStatus> status_writer(participant, status_topic, status_qos);
  ASSERT_TRUE(doa_writer.wait_for_readers(1, 5s));

  std::int64_t sent_doas = 0;
  std::int64_t clean_doas = 0;
  std::int64_t expected[dds::kSampleProblemCount] = {};
  auto send = [&](const dronetrack_Doa& sample, SampleProblem problem) {
    doa_writer.write(sample);
    ++sent_doas;
    if (problem == SampleProblem::none) ++clean_doas;
    ++expected[static_cast<int>(problem)];
    // Keep the reader's per-array history (keep-last 64) from overflowing: let the fusion
    // take what arrived.
    if (sent_doas % 16 == 0) service.poll(1ms);
  };
  auto clean_doa = [&](std::size_t array, double time_s, doa::DoaMeasurement& measurement) {
    measurement = {};
    measurement.array_id = site.arrays[array].geometry.id;
    measurement.time_s = time_s;
    measurement.direction = (drone_m - site.arrays[array].geometry.centre_site_m()).normalized();
    measurement.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-4;
    measurement.quality = 0.9;
    measurement.snr_db = 20.0;
  };

  std::mt19937_64 random(6);
  const double nasty[] = {std::numeric_limits<double>::quiet_NaN(),
                          std::numeric_limits<double>::infinity(),
                          -std::numeric_limits<double>::infinity(), 1e308, -1e308};
  doa::DoaMeasurement measurement;
  dronetrack_Doa sample{};
  for (int frame = 0; frame < 80; ++frame) {  // 4 s at 20 DOAs per second per array
    const double time_s = 0.05 * frame;
    for (std::size_t array = 0; array < 3; ++array) {
      clean_doa(array, time_s, measurement);
      dds::to_idl(measurement, 0, sample);
      send(sample, SampleProblem::none);
    }
    // One of each deliberate defect every few frames.
    if (frame % 8 == 3) {
      clean_doa(0, time_s, measurement);
      dds::to_idl(measurement, 0, sample);
      dronetrack_Doa bad = sample;
      bad.direction[2] = std::numeric_limits<double>::quiet_NaN();
      send(bad, SampleProblem::non_finite);
      bad = sample;
      bad.azel_covariance_rad2[0] = std::numeric_limits<double>::infinity();
      send(bad, SampleProblem::non_finite);
      bad = sample;
      bad.array_id[0] = '\0';
      send(bad, SampleProblem::empty_key);
      bad = sample;
      dds::copy_bounded(bad.array_id, "N9");
      send(bad, SampleProblem::unknown_array);
      bad = sample;
      bad.time_ns = -1'000'000'000;
      send(bad, SampleProblem::absurd_time);
      bad = sample;
      bad.time_ns = std::numeric_limits<std::int64_t>::max();
      send(bad, SampleProblem::absurd_time);
      bad = sample;
      bad.time_ns = sample.time_ns + 3'600'000'000'000;  // an hour ahead of everything else
      send(bad, SampleProblem::absurd_time);
      bad = sample;
      bad.direction[0] *= 3.0;
      send(bad, SampleProblem::bad_value);
      bad = sample;
      bad.azel_covariance_rad2[1] = 1.0;  // |cov| > sqrt(var_az var_el)
      send(bad, SampleProblem::bad_value);
      bad = sample;
      bad.ambiguity = 200;
      send(bad, SampleProblem::bad_value);
    }
    // Random fuzz: every field drawn at random, then one defect forced so none is valid.
    for (int k = 0; k < 3; ++k) {
      dronetrack_Doa fuzz{};
      const char* ids[] = {"N1", "N2", "N3", "", "n1", "N1 "};
      dds::copy_bounded(fuzz.array_id, ids[random() % 6]);
      // A random direction of length 0.5 or 2: never a unit vector.
      Eigen::Vector3d direction = Eigen::Vector3d::Zero();
      while (direction.norm() < 1e-3) {
        for (int axis = 0; axis < 3; ++axis) {
          direction[axis] = std::uniform_real_distribution(-1.0, 1.0)(random);
        }
      }
      direction = direction.normalized() * (random() % 2 ? 0.5 : 2.0);
      for (int axis = 0; axis < 3; ++axis) fuzz.direction[axis] = direction[axis];
      fuzz.quality = std::uniform_real_distribution(-2.0, 2.0)(random);
      fuzz.azel_covariance_rad2[0] = fuzz.azel_covariance_rad2[2] = 1e-4;
      fuzz.source_index = static_cast<std::int32_t>(random() % 5) - 1;
      fuzz.ambiguity = static_cast<std::uint8_t>(random() % 4);
      fuzz.time_ns = sample.time_ns;
      const double value = nasty[random() % 5];
      switch (random() % 4) {
        case 0:
          fuzz.direction[random() % 3] = value;
          break;
        case 1:
          fuzz.snr_db = value;
          break;
        case 2:
          fuzz.azel_covariance_rad2[random() % 3] = value;
          break;
        default:
          fuzz.elevation_deg = value;
          break;
      }
      // What the intake must call it: the first check that fails, in its order. A finite
      // nasty value may be harmless where it landed, but the random direction is never a unit
      // vector, so a sample with a known key is then a bad value.
      const std::string id = fuzz.array_id;
      SampleProblem problem = SampleProblem::bad_value;
      if (id.empty()) {
        problem = SampleProblem::empty_key;
      } else if (id != "N1" && id != "N2" && id != "N3") {
        problem = SampleProblem::unknown_array;
      } else if (!std::isfinite(value)) {
        problem = SampleProblem::non_finite;
      }
      send(fuzz, problem);
    }
    // A status per array each second, and a few bad ones.
    if (frame % 20 == 0) {
      for (const auto& array : site.arrays) {
        doa::NodeStatus status;
        status.array_id = array.geometry.id;
        status.sample_rate_hz = 48000.0;
        dronetrack_NodeStatus status_sample{};
        dds::to_idl(status, dds::seconds_to_ns(time_s), status_sample);
        status_writer.write(status_sample);
      }
      // NodeStatus is keep-last 1 per array: take the good one before the bad one replaces it.
      service.poll(1ms);
      dronetrack_NodeStatus bad{};
      dds::copy_bounded(bad.array_id, "N2");
      bad.level_dbfs = std::numeric_limits<double>::quiet_NaN();
      status_writer.write(bad);
    }
  }
  // Let the fusion take everything, then run out the remaining ticks.
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (service.counters().doa_received < sent_doas &&
         std::chrono::steady_clock::now() < deadline) {
    service.poll(50ms);
  }
  service.finish();

  const IntakeCounters& counters = service.counters();
  ASSERT_EQ(counters.doa_received, sent_doas);
  for (int kind = 1; kind < dds::kSampleProblemCount; ++kind) {
    EXPECT_EQ(counters.doa_problems[kind], expected[kind])
        << dds::to_string(static_cast<SampleProblem>(kind));
  }
  EXPECT_GT(expected[static_cast<int>(SampleProblem::non_finite)], 50);
  EXPECT_EQ(counters.doa_accepted + counters.doa_rejected_by_engine, clean_doas);
  EXPECT_EQ(counters.doa_accepted, clean_doas) << "no clean DOA may be pushed out by the garbage";
  EXPECT_EQ(counters.status_problems[static_cast<int>(SampleProblem::non_finite)], 4);
  EXPECT_TRUE(service.node_alive("N1") && service.node_alive("N2") && service.node_alive("N3"));

  // The clean stream alone decides the picture: one confirmed track on the drone.
  ASSERT_FALSE(last.tracks_.empty());
  int confirmed = 0;
  for (const auto& track : last.tracks_) {
    if (track.status != fusion::TrackStatus::confirmed) continue;
    ++confirmed;
    EXPECT_LT((track.position_m - drone_m).norm(), 2.0) << track.position_m.transpose();
  }
  EXPECT_EQ(confirmed, 1);

  // /metrics says the same, against the test's own known counts.
  metrics.set_intake_counters(counters);
  const test::Exposition exposed = test::check_exposition(metrics.text());
  ASSERT_TRUE(exposed.ok()) << exposed.problems.front();
  for (int kind = 1; kind < dds::kSampleProblemCount; ++kind) {
    const std::string problem = dds::to_string(static_cast<SampleProblem>(kind));
    EXPECT_EQ(exposed.value("dronetrack_dds_samples_rejected_total{topic=\"Doa\",problem=\"" +
                            problem + "\"}"),
              expected[kind])
        << problem;
  }
  EXPECT_EQ(
      exposed.value(
          "dronetrack_dds_samples_rejected_total{topic=\"NodeStatus\",problem=\"non_finite\"}"),
      4);
  EXPECT_EQ(exposed.value("dronetrack_dds_doa_samples_received_total"), sent_doas);
  EXPECT_EQ(exposed.value("dronetrack_fusion_doas_total{verdict=\"accepted\"}"), clean_doas);
  EXPECT_EQ(exposed.value("dronetrack_tracks{status=\"confirmed\",class=\"drone\"}") +
                exposed.value("dronetrack_tracks{status=\"confirmed\",class=\"unknown\"}") +
                exposed.value("dronetrack_tracks{status=\"confirmed\",class=\"ground\"}") +
                exposed.value("dronetrack_tracks{status=\"confirmed\",class=\"aircraft\"}"),
            confirmed);
}

// Track ids are never reused, so an ended track's Track instance, and every Alert instance
// (zone, track id), must be unregistered by the fusion, or every subscriber keeps it (disposed,
// empty) for the life of the process, and the fusion's transient-local Track writer keeps its
// last sample (issue 18, the soak). A drone inside a zone is tracked for 4 s and then falls
// silent while a second drone goes on: once the first track is deleted and a subscriber has
// taken what arrived, the subscriber keeps neither that track nor its alerts, only the live
// track.
TEST(DdsFusionIntake, SubscribersDropEndedTracksAndTheirAlerts) {
  dds::testing::use_loopback();
  std::vector<std::string> warnings;
  config::LoadOptions load_options;
  load_options.check_recordings = false;
  nlohmann::json site_json = nlohmann::json::parse(kSite);
  site_json["zones"] = nlohmann::json::parse(
      R"([{"name": "yard", "polygon_m": [[-25, -25], [25, -25], [25, 25], [-25, 25]]}])");
  site_json["alerts"] = nlohmann::json::parse(
      R"({"classes": ["drone", "ground", "aircraft", "unknown"], "min_confirmed_s": 0})");
  const config::SiteConfig site =
      config::parse_site_config(site_json.dump(), ".", warnings, load_options);
  const Eigen::Vector3d ending_m(10.0, 20.0, 30.0);    // inside the yard, silent after 4 s
  const Eigen::Vector3d staying_m(-45.0, 10.0, 40.0);  // outside it, heard throughout

  dds::Participant participant(123);
  LastTracks last;
  DdsFusionService service(site, participant, {&last});
  dds::Topic<dronetrack_Doa> doa_topic(participant);
  dds::Topic<dronetrack_Track> track_topic(participant);
  dds::Topic<dronetrack_Alert> alert_topic(participant);
  dds::Qos doa_qos, track_qos, alert_qos;
  dds::doa_writer_qos(doa_qos);
  dds::track_reader_qos(track_qos);
  dds::alert_reader_qos(alert_qos);
  dds::Writer<dronetrack_Doa> doa_writer(participant, doa_topic, doa_qos);
  dds::Reader<dronetrack_Track> track_reader(participant, track_topic, track_qos);
  dds::Reader<dronetrack_Alert> alert_reader(participant, alert_topic, alert_qos);
  ASSERT_TRUE(doa_writer.wait_for_readers(1, 5s));

  std::set<int> track_ids;
  std::set<std::pair<std::string, int>> alert_keys;
  auto take_outputs = [&] {
    for (bool more = true; more;) {
      dds::Samples<dronetrack_Track> samples = track_reader.take();
      for (std::size_t i = 0; i < samples.size(); ++i) track_ids.insert(samples.data(i).id);
      more = samples.size() == dds::Samples<dronetrack_Track>::kMaxSamples;
    }
    for (bool more = true; more;) {
      dds::Samples<dronetrack_Alert> samples = alert_reader.take();
      for (std::size_t i = 0; i < samples.size(); ++i) {
        alert_keys.emplace(samples.data(i).zone, samples.data(i).track_id);
      }
      more = samples.size() == dds::Samples<dronetrack_Alert>::kMaxSamples;
    }
  };
  std::int64_t sent_doas = 0;
  doa::DoaMeasurement measurement;
  dronetrack_Doa sample{};
  for (int frame = 0; frame < 200; ++frame) {  // 10 s at 20 DOAs per second per array
    const double time_s = 0.05 * frame;
    for (std::size_t array = 0; array < 3; ++array) {
      for (const Eigen::Vector3d* drone_m : {&ending_m, &staying_m}) {
        if (drone_m == &ending_m && time_s >= 4.0) continue;
        measurement = {};
        measurement.array_id = site.arrays[array].geometry.id;
        measurement.time_s = time_s;
        measurement.direction =
            (*drone_m - site.arrays[array].geometry.centre_site_m()).normalized();
        measurement.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-4;
        measurement.quality = 0.9;
        measurement.snr_db = 20.0;
        measurement.source_index = drone_m == &ending_m ? 0 : 1;
        dds::to_idl(measurement, 0, sample);
        doa_writer.write(sample);
        ++sent_doas;
      }
    }
    if (frame % 8 == 0) {
      service.poll(1ms);
      take_outputs();
    }
  }
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (service.counters().doa_received < sent_doas &&
         std::chrono::steady_clock::now() < deadline) {
    service.poll(50ms);
  }
  take_outputs();

  // The picture the check relies on: one live track, on the drone still heard.
  ASSERT_EQ(service.counters().doa_received, sent_doas);
  ASSERT_EQ(last.tracks_.size(), 1u);
  EXPECT_LT((last.tracks_[0].position_m - staying_m).norm(), 3.0);
  const int live_id = last.tracks_[0].id;
  ASSERT_EQ(track_ids.count(live_id), 1u);
  ASSERT_GE(track_ids.size(), 2u) << "the silent drone's track was never published";
  ASSERT_FALSE(alert_keys.empty()) << "the track in the yard raised no alert";

  // Whether a reader still keeps an instance: reading it by handle fails with
  // PRECONDITION_NOT_MET once the reader has dropped it. Room for as many buffers as the reader's
  // largest loan (dds::Samples takes up to kMaxSamples): Cyclone 0.10 hands a loan back by
  // filling that many pointers, whatever bufsz and maxs say (an array of one here had 63 of them
  // written past it, on the stack: clang's ASan build crashed on the return).
  const auto reader_keeps = [](const auto& reader, const auto& key) {
    const dds_instance_handle_t handle = dds_lookup_instance(reader.handle(), &key);
    if (handle == DDS_HANDLE_NIL) return false;
    std::array<void*, dds::Samples<dronetrack_Track>::kMaxSamples> buffers{};
    std::array<dds_sample_info_t, dds::Samples<dronetrack_Track>::kMaxSamples> infos{};
    const dds_return_t read =
        dds_read_instance(reader.handle(), buffers.data(), infos.data(), 1, 1, handle);
    if (read > 0) dds_return_loan(reader.handle(), buffers.data(), read);
    return read >= 0;
  };
  dronetrack_Track track_key{};
  track_key.id = live_id;
  EXPECT_TRUE(reader_keeps(track_reader, track_key)) << "the live track must be there";
  for (int id : track_ids) {
    if (id == live_id) continue;
    track_key.id = id;
    EXPECT_FALSE(reader_keeps(track_reader, track_key)) << "ended track " << id << " is kept";
  }
  for (const auto& [zone, id] : alert_keys) {
    dronetrack_Alert alert_key{};
    dds::copy_bounded(alert_key.zone, zone);
    alert_key.track_id = id;
    EXPECT_FALSE(reader_keeps(alert_reader, alert_key))
        << "alert instance (" << zone << ", " << id << ") is kept";
  }
  service.finish();
}

// A secure site's fusion reads each array's partition and refuses a sample whose array id is
// not its writer's partition: N1's writer (partition "array.N1") claiming to be N2 is counted
// as foreign_partition and never reaches the engine; writers in the right partitions pass, and
// a writer outside the per-array partitions (the default partition) is not even matched.
TEST(DdsFusionIntake, SecureSiteRefusesSamplesOutsideTheirArraysPartition) {
  dds::testing::use_loopback();
  std::vector<std::string> warnings;
  config::LoadOptions load_options;
  load_options.check_recordings = false;
  const config::SiteConfig site = config::parse_site_config(kSite, ".", warnings, load_options);

  dds::Participant participant(122);
  LastTracks last;
  FusionServiceOptions options;
  options.array_partitions = true;
  DdsFusionService service(site, participant, {&last}, options);
  dds::Topic<dronetrack_Doa> doa_topic(participant);
  const auto writer_in = [&](const std::string& array_id) {
    dds::Qos qos;
    dds::doa_writer_qos(qos);
    if (!array_id.empty()) qos.partitions({dds::array_partition(array_id)});
    return std::make_unique<dds::Writer<dronetrack_Doa>>(participant, doa_topic, qos);
  };
  const auto n1 = writer_in("N1");
  const auto n2 = writer_in("N2");
  const auto outside = writer_in("");
  ASSERT_TRUE(n1->wait_for_readers(1, 5s));
  ASSERT_TRUE(n2->wait_for_readers(1, 5s));
  EXPECT_EQ(outside->matched_readers(), 0U);

  const Eigen::Vector3d drone_m(10.0, 20.0, 30.0);
  dronetrack_Doa sample{};
  for (int frame = 0; frame < 10; ++frame) {
    for (const char* id : {"N1", "N2"}) {
      doa::DoaMeasurement measurement;
      measurement.array_id = id;
      measurement.time_s = 0.05 * frame;
      const auto array = static_cast<std::size_t>(site.array_index(id));
      measurement.direction = (drone_m - site.arrays[array].geometry.centre_site_m()).normalized();
      measurement.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-4;
      measurement.quality = 0.9;
      dds::to_idl(measurement, 0, sample);
      (std::string(id) == "N1" ? *n1 : *n2).write(sample);
      if (std::string(id) == "N2") n1->write(sample);  // N1 speaking for N2
      outside->write(sample);
    }
  }
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (service.counters().doa_received < 30 && std::chrono::steady_clock::now() < deadline) {
    service.poll(50ms);
  }
  service.finish();
  const IntakeCounters& counters = service.counters();
  EXPECT_EQ(counters.doa_received, 30);  // 10 x (N1, N2, N1-as-N2); nothing from outside
  EXPECT_EQ(counters.doa_problems[static_cast<int>(SampleProblem::foreign_partition)], 10);
  EXPECT_EQ(counters.doa_accepted + counters.doa_rejected_by_engine, 20);
}

}  // namespace
}  // namespace dronetrack::apps
