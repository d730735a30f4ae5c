// A moving node over DDS (issue 15), with the real binary: `pose-publish` plays a pose file on
// the ArrayPose topic in real time while `node --realtime --pose-topic` replays the array's
// recording in step (same --epoch); this test subscribes to Doa like a fusion would. The array
// turns at 10 deg/s and carries its source with it (the source is fixed in the array's own
// frame, so the audio is a constant plane wave): every DOA must arrive stamped moving, from the
// pose at its time (centre on the path), pointing along the array-frame direction turned by the
// heading AT ITS TIME. A DOA turned by the config's yaw, or by a pose 0.1 s off, is off by
// 20 deg or 1 deg.
#include <gtest/gtest.h>
#include <sndfile.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"
#include "doa/array_geometry.hpp"
#include "doa/pose_track.hpp"
#include "tests/dds/dds_test_support.hpp"
#include "tests/dds/process_support.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace {

using namespace std::chrono_literals;
using dronetrack::dds::testing::Clock;
namespace fs = std::filesystem;

constexpr int kDomain = 137;
constexpr int kRate = 16000;
constexpr double kSeconds = 4.0;

using dronetrack::dds::testing::Process;
using dronetrack::dds::testing::read_text;
using dronetrack::dds::testing::unix_now_s;

double heading_deg(double time_s) { return -20.0 + 10.0 * time_s; }
Eigen::Vector3d origin_m(double time_s) { return {5.0 + 1.5 * time_s, -3.0, 2.0}; }

TEST(DdsMovingNode, DoasArriveStampedWithThePoseAtTheirTime) {
  dronetrack::dds::testing::use_loopback();
  const fs::path dir =
      fs::temp_directory_path() / ("dronetrack-moving-" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);

  // The audio: a plane wave from a fixed direction of the array's own frame.
  const dronetrack::doa::ArrayGeometry array = dronetrack::doa::testing::tetrahedron(0.0, "M1");
  const Eigen::Vector3d in_array_frame = dronetrack::doa::direction_from_azel_deg(40.0, 25.0);
  {
    namespace synthetic = dronetrack::doa::testing;
    const auto frames = static_cast<std::size_t>(kSeconds * kRate);
    synthetic::Recording recording = synthetic::silent_recording(4, frames);
    const synthetic::BandNoise source(static_cast<int>(frames), kRate, 1000.0, 4000.0, 21);
    synthetic::add_source(recording, array, in_array_frame, source, 0.05);
    synthetic::add_sensor_noise(recording, kRate, 200.0, 7000.0, 0.01, 5);
    SF_INFO info{};
    info.samplerate = kRate;
    info.channels = 4;
    info.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
    SNDFILE* handle = sf_open((dir / "M1.wav").c_str(), SFM_WRITE, &info);
    ASSERT_NE(handle, nullptr);
    sf_writef_float(handle, recording.interleaved.data(), static_cast<sf_count_t>(frames));
    sf_close(handle);
  }
  {
    std::ofstream pose(dir / "pose.jsonl");
    for (int i = 0; i <= 45; ++i) {  // 10 Hz, 0 .. 4.5 s
      const double t = 0.1 * i;
      const Eigen::Vector3d p = origin_m(t);
      pose << "{\"t\": " << t << ", \"position_m\": [" << p.x() << ", " << p.y() << ", " << p.z()
           << "], \"yaw_deg\": " << heading_deg(t) << "}\n";
    }
    // The config's pose is elsewhere and level: DOAs must not use it.
    std::ofstream(dir / "site.json") << R"({"arrays": [{"id": "M1", "position_m": [0, 0, 1.5],
      "yaw_deg": 0, "recording": "M1.wav", "pose_topic": true,
      "mics_m": [[0,0,0.5], [0.4714,0,-0.1667], [-0.2357,0.4082,-0.1667], [-0.2357,-0.4082,-0.1667]]}],
      "doa": {"tdoa_tracker": "per_frame", "ground_echo": false},
      "fusion": {"single_array_start": true}})";
  }

  namespace dds = dronetrack::dds;
  dds::Participant participant(kDomain);
  dds::Topic<dronetrack_Doa> topic(participant);
  dds::Qos qos;
  dds::doa_reader_qos(qos);
  dds::Reader<dronetrack_Doa> reader(participant, topic, qos);

  const double epoch = std::floor(unix_now_s()) + 4.0;  // both have discovered each other by then
  char epoch_text[32];
  std::snprintf(epoch_text, sizeof epoch_text, "%.3f", epoch);
  const std::string binary = DRONETRACK_BINARY;
  const std::string domain = std::to_string(kDomain);
  Process poses({binary, "pose-publish", "--array", "M1", "--pose-file",
                 (dir / "pose.jsonl").string(), "--epoch", epoch_text, "--domain", domain},
                "/dev/null", dir / "pose.err");
  // The fusion process takes the same stream: the poses travel inside the DOAs, it never reads
  // ArrayPose.
  Process fusion({binary, "fusion", (dir / "site.json").string(), "--domain", domain,
                  "--tracks-out", (dir / "tracks.jsonl").string()},
                 "/dev/null", dir / "fusion.err");
  Process node({binary, "node", (dir / "site.json").string(), "--array", "M1", "--realtime",
                "--epoch", epoch_text, "--domain", domain},
               "/dev/null", dir / "node.err");

  std::vector<dronetrack::doa::DoaMeasurement> doas;
  const std::vector<std::string> ids{"M1"};
  const auto deadline =
      Clock::now() + std::chrono::duration<double>(epoch + kSeconds + 4.0 - unix_now_s());
  while (Clock::now() < deadline && !node.wait_exit(0s)) {
    reader.wait(100ms);
    dds::Samples<dronetrack_Doa> samples = reader.take();
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (!samples.info(i).valid_data) continue;
      dronetrack::doa::DoaMeasurement doa;
      ASSERT_EQ(dds::from_idl(samples.data(i), ids, doa), dds::SampleProblem::none);
      doas.push_back(doa);
    }
  }
  ASSERT_EQ(node.wait_exit(10s), 0) << read_text(dir / "node.err");
  ASSERT_EQ(poses.wait_exit(10s), 0) << read_text(dir / "pose.err");
  // Frames every 50 ms over ~4 s; a few at the start wait for the detector's noise floor.
  EXPECT_GE(doas.size(), 50U) << read_text(dir / "node.err");
  double worst_deg = 0.0;
  for (const auto& doa : doas) {
    EXPECT_TRUE(doa.pose.moving);
    const Eigen::Vector3d expected =
        dronetrack::doa::attitude_to_site(heading_deg(doa.time_s), 0, 0) * in_array_frame;
    worst_deg = std::max(worst_deg, dronetrack::doa::angle_between_deg(doa.direction, expected));
    const Eigen::Vector3d centre =
        origin_m(doa.time_s) + dronetrack::doa::attitude_to_site(heading_deg(doa.time_s), 0, 0) *
                                   dronetrack::doa::mic_centroid_m(array);
    EXPECT_LT((doa.pose.centre_m - centre).norm(), 1e-6) << doa.time_s;
  }
  std::printf("%zu DOAs over DDS, worst error against the heading at their time %.3f deg\n",
              doas.size(), worst_deg);
  EXPECT_LT(worst_deg, 1.0);

  // The fusion took every one of them as a valid moving-array DOA (pose checked on intake).
  std::this_thread::sleep_for(1s);  // its reorder window
  fusion.signal(SIGTERM);
  ASSERT_EQ(fusion.wait_exit(10s), (128 + SIGTERM) << 8) << read_text(dir / "fusion.err");
  const std::string fusion_log = read_text(dir / "fusion.err");
  long received = -1;
  long accepted = -1;
  long malformed = -1;
  const auto summary = fusion_log.find("DOAs received");
  ASSERT_NE(summary, std::string::npos) << fusion_log;
  const auto at = fusion_log.rfind("fusion: ", summary);
  ASSERT_NE(at, std::string::npos) << fusion_log;
  ASSERT_EQ(
      std::sscanf(fusion_log.c_str() + at, "fusion: %ld DOAs received, %ld accepted, %ld malformed",
                  &received, &accepted, &malformed),
      3)
      << fusion_log;
  std::printf("fusion: %ld DOAs received, %ld accepted, %ld malformed\n", received, accepted,
              malformed);
  EXPECT_GE(received, static_cast<long>(doas.size()) - 2) << fusion_log;
  EXPECT_EQ(accepted, received) << fusion_log;
  EXPECT_EQ(malformed, 0) << fusion_log;
  fs::remove_all(dir);
}

}  // namespace
