// JSON-lines outputs (SPEC 3.2) parse back to what was written; the fusion driver reports at
// the output rate, in time order, only once the reorder window has passed; `replay --doa-in`
// reads DOA lines back into the measurements that were written.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "apps/doa_file_replay.hpp"
#include "apps/fusion_driver.hpp"
#include "apps/jsonl_output.hpp"
#include "doa/array_geometry.hpp"
#include "doa/pose_sample.hpp"
#include "eval/readers.hpp"

namespace dronetrack::apps {
namespace {

TEST(JsonLines, DoaLineCarriesTheSpecFields) {
  doa::DoaMeasurement doa;
  doa.array_id = "A1";
  doa.time_s = 12.35;
  doa.direction = doa::direction_from_azel_deg(-170.0, 25.0);
  doa.quality = 0.75;
  doa.azel_covariance_rad2 = Eigen::Vector2d(1e-6, 4e-6).asDiagonal();
  char buffer[1024];
  const int length = format_doa_line(doa, buffer, sizeof buffer);
  ASSERT_GT(length, 0);
  const auto line = nlohmann::json::parse(std::string(buffer, static_cast<std::size_t>(length)));
  EXPECT_DOUBLE_EQ(line.at("t").get<double>(), 12.35);
  EXPECT_EQ(line.at("array"), "A1");
  EXPECT_NEAR(line.at("azimuth_deg").get<double>(), -170.0, 1e-4);
  EXPECT_NEAR(line.at("elevation_deg").get<double>(), 25.0, 1e-4);
  const auto direction = line.at("direction").get<std::vector<double>>();
  ASSERT_EQ(direction.size(), 3u);
  EXPECT_NEAR(Eigen::Vector3d(direction[0], direction[1], direction[2]).norm(), 1.0, 1e-8);
  EXPECT_NEAR(line.at("azel_std_deg")[1].get<double>(), 2e-3 * 180.0 / std::numbers::pi, 1e-4);
  EXPECT_DOUBLE_EQ(line.at("quality").get<double>(), 0.75);
}

// Every block of a DOA line, characters as written since the format was first defined (the
// printf formats of docs/contract.md): values with ties at the printed digit, a negative that
// rounds to zero, a large one.
TEST(JsonLines, DoaLineCharactersAreTheContractsFormats) {
  doa::DoaMeasurement doa;
  doa.array_id = "north-1";
  doa.time_s = 123456.0000005;
  doa.direction = Eigen::Vector3d(0.6, -0.8, -1e-12);
  doa.quality = 0.00005;
  doa.snr_db = -3.125;
  doa.source_index = 2;
  doa.azel_covariance_rad2 << 4e-6, -1.2e-6, -1.2e-6, 9e-6;
  doa.ambiguity = doa::DoaAmbiguity::cone;
  doa.ambiguity_axis = Eigen::Vector3d(0.0, 0.6, 0.8);
  doa.cone_angle_rad = 1.25;
  doa.cone_angle_variance_rad2 = 0.0004;
  doa.cone_peak_count = 2;
  doa.cone_peak_angle_rad = {1.25, 0.5, 0.0, 0.0};
  doa.cone_peak_weight = {0.875, 0.125, 0.0, 0.0};
  doa.pose = {Eigen::Vector3d(10.00005, -20.0, 1e7),
              Eigen::Quaterniond(doa::attitude_to_site(35.0, 5.0, -3.0)), true};
  doa.acoustic.valid = true;
  doa.acoustic.fundamental_hz = 165.125;
  doa.acoustic.comb_strength = 0.5;
  doa.acoustic.harmonic_count = 12;
  doa.acoustic.broadband_share = 0.25;
  doa.acoustic.comb_persistence = 1.0;
  doa.acoustic.fundamental_spread = 0.015625;
  doa.acoustic.level_modulation_db = -0.0625;
  doa.acoustic.history_s = 2.5;
  char buffer[2048];
  const int length = format_doa_line(doa, buffer, sizeof buffer);
  ASSERT_GT(length, 0);
  // The fields every line has, then the ambiguity's.
  const std::string head =
      R"({"t":123456.000001,"array":"north-1",)"
      R"("direction":[0.600000000,-0.800000000,-0.000000000],"azimuth_deg":-53.13010,)"
      R"("elevation_deg":-0.00000,"quality":0.0001,"snr_db":-3.12,"source":2,)";
  EXPECT_EQ(
      std::string(buffer, static_cast<std::size_t>(length)),
      head +
          R"("ambiguity":"cone","azel_std_deg":[0.114592,0.171887],"azel_correlation":-0.200000,)"
          R"("pose":{"centre_m":[10.0000,-20.0000,10000000.0000],)"
          R"("attitude_deg":[35.0000,5.0000,-3.0000]},)"
          R"("cone":{"axis":[0.000000000,0.600000000,0.800000000],"angle_deg":71.61972,)"
          R"("angle_std_deg":1.145916,"peaks_deg":[71.61972,28.64789],)"
          R"("peak_weights":[0.87500,0.12500]},"acoustic":{"fundamental_hz":165.12,)"
          R"("comb_strength":0.5000,"harmonics":12,"broadband_share":0.2500,)"
          R"("comb_persistence":1.0000,"fundamental_spread":0.01562,"level_modulation_db":-0.062,)"
          R"("history_s":2.50}})");
  doa.ambiguity = doa::DoaAmbiguity::mirror_up_down;
  doa.pose.moving = false;
  doa.acoustic.valid = false;
  const int mirror_length = format_doa_line(doa, buffer, sizeof buffer);
  ASSERT_GT(mirror_length, 0);
  EXPECT_EQ(
      std::string(buffer, static_cast<std::size_t>(mirror_length)),
      head +
          R"("ambiguity":"mirror_up_down","azel_std_deg":[0.114592,0.171887],)"
          R"("azel_correlation":-0.200000,"mirror_normal":[0.000000000,0.600000000,0.800000000]})");
  // A line that does not fit says so (the writers refuse it) rather than come back cut.
  EXPECT_GE(format_doa_line(doa, buffer, 64), 64);
}

// What a moving two-mic array measured survives the DOA line: written, then read back as
// `replay --doa-in` reads it.
TEST(JsonLines, ConeAndPoseBlocksRoundTripThroughTheReader) {
  doa::DoaMeasurement doa;
  doa.array_id = "H1";
  doa.time_s = 4.25;
  doa.ambiguity = doa::DoaAmbiguity::cone;
  doa.ambiguity_axis = Eigen::Vector3d(0.6, 0.8, 0.0);
  doa.cone_angle_rad = 1.2;
  doa.cone_angle_variance_rad2 = 0.02 * 0.02;
  doa.cone_peak_count = 3;
  doa.cone_peak_angle_rad = {1.2, 0.4, 2.5, 0.0};
  doa.cone_peak_weight = {0.9, 0.5, 0.25, 0.0};
  doa.pose = {Eigen::Vector3d(10.0, -20.0, -5.0),
              Eigen::Quaterniond(doa::attitude_to_site(35.0, 5.0, -3.0)), true};
  doa.acoustic.valid = true;
  doa.acoustic.fundamental_hz = 120.0;
  char buffer[2048];
  const int length = format_doa_line(doa, buffer, sizeof buffer);
  ASSERT_GT(length, 0);
  const std::string text(buffer, static_cast<std::size_t>(length));
  const auto records = eval::parse_doas(text + "\n", "D.jsonl");
  ASSERT_EQ(records.size(), 1u);
  const eval::DoaRecord& record = records[0];
  ASSERT_TRUE(record.cone.has_value()) << text;
  EXPECT_LT((record.cone->axis - doa.ambiguity_axis).norm(), 1e-8);
  EXPECT_NEAR(record.cone->angle_deg, 1.2 * 180.0 / std::numbers::pi, 1e-4);
  EXPECT_NEAR(record.cone->angle_std_deg, 0.02 * 180.0 / std::numbers::pi, 1e-5);
  ASSERT_EQ(record.cone->peaks_deg.size(), 3u);
  EXPECT_NEAR(record.cone->peaks_deg[2], 2.5 * 180.0 / std::numbers::pi, 1e-4);
  EXPECT_NEAR(record.cone->peak_weights[1], 0.5, 1e-9);
  ASSERT_TRUE(record.pose.has_value());
  EXPECT_LT((record.pose->centre_m - doa.pose.centre_m).norm(), 1e-4);
  EXPECT_LT((record.pose->attitude_deg - Eigen::Vector3d(35.0, 5.0, -3.0)).norm(), 1e-3);
  EXPECT_FALSE(record.mirror_normal.has_value());
  EXPECT_TRUE(record.acoustic.valid);

  doa.ambiguity = doa::DoaAmbiguity::mirror_up_down;
  doa.ambiguity_axis = Eigen::Vector3d::UnitZ();
  doa.pose.moving = false;
  const int mirror_length = format_doa_line(doa, buffer, sizeof buffer);
  const auto mirror = eval::parse_doas(
      std::string(buffer, static_cast<std::size_t>(mirror_length)) + "\n", "D.jsonl");
  ASSERT_TRUE(mirror[0].mirror_normal.has_value());
  EXPECT_FALSE(mirror[0].cone.has_value());
  EXPECT_FALSE(mirror[0].pose.has_value());
}

TEST(JsonLines, OneArrayTrackSaysSoAndEvalReadsIt) {
  fusion::TrackReport track;
  track.id = 5;
  track.one_array = true;
  track.hypotheses = 7;
  track.covariance.diagonal().head<3>() = Eigen::Vector3d(400.0, 900.0, 100.0);
  char buffer[1024];
  const int length = format_track_line(3.0, track, buffer, sizeof buffer);
  ASSERT_GT(length, 0);
  const std::string text(buffer, static_cast<std::size_t>(length));
  const auto line = nlohmann::json::parse(text);
  EXPECT_EQ(line.at("one_array"), true);
  EXPECT_EQ(line.at("hypotheses"), 7);
  const auto records = eval::parse_tracks(text + "\n", "T.jsonl");
  ASSERT_EQ(records.size(), 1u);
  EXPECT_TRUE(records[0].one_array);
  EXPECT_EQ(records[0].position_std_m, Eigen::Vector3d(20.0, 30.0, 10.0));
  track.one_array = false;
  const int plain = format_track_line(3.0, track, buffer, sizeof buffer);
  EXPECT_FALSE(nlohmann::json::parse(std::string(buffer, static_cast<std::size_t>(plain)))
                   .contains("one_array"));
}

TEST(JsonLines, TrackLineCarriesTheSpecFields) {
  fusion::TrackReport track;
  track.id = 3;
  track.position_m = {1.5, -2.25, 30.0};
  track.velocity_mps = {5.0, 0.0, -1.0};
  track.covariance.diagonal().head<3>() = Eigen::Vector3d(4.0, 9.0, 16.0);
  track.status = fusion::TrackStatus::coasting;
  char buffer[1024];
  const int length = format_track_line(7.5, track, buffer, sizeof buffer);
  const auto line = nlohmann::json::parse(std::string(buffer, static_cast<std::size_t>(length)));
  EXPECT_DOUBLE_EQ(line.at("t").get<double>(), 7.5);
  EXPECT_EQ(line.at("id"), 3);
  EXPECT_EQ(line.at("position_m").get<std::vector<double>>(),
            (std::vector<double>{1.5, -2.25, 30.0}));
  EXPECT_EQ(line.at("velocity_mps").get<std::vector<double>>(),
            (std::vector<double>{5.0, 0.0, -1.0}));
  EXPECT_EQ(line.at("position_std_m").get<std::vector<double>>(),
            (std::vector<double>{2.0, 3.0, 4.0}));
  EXPECT_EQ(line.at("status"), "coasting");
  EXPECT_TRUE(line.contains("acceleration_mps2"));
}

class RecordingObserver : public FusionObserver {
 public:
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>&) override {
    ticks.push_back(time_s);
  }
  void on_time(double time_s) override { latest_time_s = time_s; }
  std::vector<double> ticks;
  double latest_time_s = 0.0;
};

config::SiteConfig two_array_site() {
  config::SiteConfig site;
  for (int i = 0; i < 2; ++i) {
    config::ArrayConfig array;
    array.geometry.id = i == 0 ? "A1" : "A2";
    array.geometry.position_m = {20.0 * i, 0.0, 1.5};
    array.geometry.mics_m = {
        {0, 0, 0.5}, {0.4714, 0, -0.1667}, {-0.2357, 0.4082, -0.1667}, {-0.2357, -0.4082, -0.1667}};
    site.arrays.push_back(array);
  }
  site.fusion.output_rate_hz = 10.0;
  site.fusion.reorder_window_s = 0.3;
  return site;
}

TEST(FusionDriver, TicksAtTheOutputRateOnlyPastTheReorderWindow) {
  RecordingObserver observer;
  FusionDriver driver(two_array_site(), {&observer});
  driver.advance_to(0.25);
  EXPECT_TRUE(observer.ticks.empty()) << "no tick may precede now - reorder window";
  driver.advance_to(1.0);
  ASSERT_EQ(observer.ticks.size(), 8u);  // 0.0 .. 0.7
  EXPECT_NEAR(observer.ticks.back(), 0.7, 1e-9);
  driver.advance_to(0.9);  // time never goes backwards
  EXPECT_EQ(observer.ticks.size(), 8u);
  EXPECT_DOUBLE_EQ(observer.latest_time_s, 1.0);
  driver.finish();
  ASSERT_EQ(observer.ticks.size(), 11u);  // up to the last time seen
  for (std::size_t i = 1; i < observer.ticks.size(); ++i) {
    EXPECT_NEAR(observer.ticks[i] - observer.ticks[i - 1], 0.1, 1e-9);
  }
}

TEST(FusionDriver, RejectedDoasAreNotForwarded) {
  class DoaCounter : public FusionObserver {
   public:
    void on_doa(const doa::DoaMeasurement&) override { ++count; }
    int count = 0;
  } counter;
  FusionDriver driver(two_array_site(), {&counter});
  doa::DoaMeasurement doa;
  doa.array_id = "A9";  // not in the site
  doa.array_index = 9;
  doa.time_s = 1.0;
  EXPECT_NE(driver.on_doa(doa), fusion::DoaVerdict::accepted);
  doa.array_id = "A1";
  doa.array_index = 0;
  doa.direction = Eigen::Vector3d(std::nan(""), 0, 1);
  EXPECT_NE(driver.on_doa(doa), fusion::DoaVerdict::accepted);
  EXPECT_EQ(counter.count, 0);
  doa.direction = Eigen::Vector3d(0, 0.6, 0.8);
  doa.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-5;
  EXPECT_EQ(driver.on_doa(doa), fusion::DoaVerdict::accepted);
  EXPECT_EQ(counter.count, 1);
}

TEST(FusionDriver, WithNoTrackObserverDoasAreCheckedAndNoTrackerRuns) {
  // A DOA-only replay: the observers take DOAs, none wants tracks.
  class DoaOnly : public RecordingObserver {
   public:
    bool wants_tracks() const override { return false; }
    void on_doa(const doa::DoaMeasurement&) override { ++doas; }
    int doas = 0;
  } doa_only;
  RecordingObserver tracks;
  FusionDriver checking(two_array_site(), {&doa_only});
  FusionDriver tracking(two_array_site(), {&doa_only, &tracks});
  EXPECT_FALSE(checking.tracking());
  EXPECT_TRUE(tracking.tracking());
  // Every verdict add() gives without tracker state, then one frame of each array for 2 s: a
  // source both see, so the tracking driver starts a track.
  std::vector<doa::DoaMeasurement> stream;
  doa::DoaMeasurement bad;
  bad.array_id = "A9";  // unknown array
  bad.array_index = 9;
  bad.time_s = 0.0;
  bad.direction = Eigen::Vector3d(0, 0, 1);
  bad.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-5;
  stream.push_back(bad);
  bad.array_id = "A1";
  bad.array_index = 0;
  bad.direction = Eigen::Vector3d(std::nan(""), 0, 1);  // non-finite
  stream.push_back(bad);
  bad.direction = Eigen::Vector3d(0, 0, 2);  // not a unit vector
  stream.push_back(bad);
  const Eigen::Vector3d source_m(10.0, 20.0, 18.0);
  const std::string ids[] = {"A1", "A2"};
  for (int frame = 0; frame < 40; ++frame) {
    for (int array = 0; array < 2; ++array) {
      doa::DoaMeasurement doa;
      doa.array_id = ids[array];
      doa.array_index = array;
      doa.time_s = 0.05 * frame;
      doa.direction = (source_m - Eigen::Vector3d(20.0 * array, 0.0, 1.5)).normalized();
      doa.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-5;
      stream.push_back(doa);
    }
  }
  for (const doa::DoaMeasurement& doa : stream) {
    EXPECT_EQ(checking.on_doa(doa), tracking.on_doa(doa)) << doa.array_id << " " << doa.time_s;
    checking.advance_to(doa.time_s);
    tracking.advance_to(doa.time_s);
  }
  checking.finish();
  tracking.finish();
  EXPECT_EQ(doa_only.doas, 2 * 80);  // the 80 valid DOAs, from each driver
  EXPECT_DOUBLE_EQ(doa_only.latest_time_s, 1.95);
  const fusion::FusionCounters& checked = checking.engine().counters();
  const fusion::FusionCounters& tracked = tracking.engine().counters();
  EXPECT_EQ(checked.accepted, 80);
  EXPECT_EQ(checked.rejected_unknown_array, tracked.rejected_unknown_array);
  EXPECT_EQ(checked.rejected_non_finite, tracked.rejected_non_finite);
  EXPECT_EQ(checked.rejected_bad_direction, tracked.rejected_bad_direction);
  EXPECT_EQ(
      checked.rejected_unknown_array + checked.rejected_non_finite + checked.rejected_bad_direction,
      3);
  EXPECT_EQ(checking.ticks_emitted(), 0);
  EXPECT_EQ(checked.tracks_started, 0);
  EXPECT_GT(tracking.ticks_emitted(), 0);
  EXPECT_FALSE(tracks.ticks.empty());
  EXPECT_GE(tracked.tracks_started, 1);
}

// Issue 16: a swap the fusion's mirror check names reaches the node's status as the observers
// (/api/nodes, the page) see it: both channels flagged `swapped`, the others not.
TEST(FusionDriver, MirrorSwapMarksTheNodeStatus) {
  class StatusKeeper : public FusionObserver {
   public:
    void on_node_status(const doa::NodeStatus& status) override { last = status; }
    doa::NodeStatus last;
  } keeper;
  config::SiteConfig site = two_array_site();
  site.arrays.push_back(site.arrays[1]);
  site.arrays[2].geometry.id = "A3";
  site.arrays[2].geometry.position_m = {10.0, 25.0, 1.5};
  site.arrays[1].geometry.position_m = {10.0, 0.0, 1.5};
  site.arrays[1].channel_map = {0, 1, 3, 2};  // mic 2 on input 3: named in the warning
  FusionDriver driver(site, {&keeper});
  // A drone circling A2; A2's mics 1 and 2 swapped: its DOAs mirrored through their plane.
  const Eigen::Vector3d normal =
      (site.arrays[1].geometry.mics_m[1] - site.arrays[1].geometry.mics_m[2]).normalized();
  for (double t = 0.0; t < 30.0; t += 0.05) {
    const Eigen::Vector3d drone(10.0 + 12.0 * std::cos(0.5 * t), 12.0 * std::sin(0.5 * t),
                                15.0 + 5.0 * std::sin(0.2 * t));
    for (int a = 0; a < 3; ++a) {
      doa::DoaMeasurement doa;
      doa.array_id = site.arrays[a].geometry.id;
      doa.array_index = a;
      doa.time_s = t;
      doa.direction = (drone - site.arrays[a].geometry.centre_site_m()).normalized();
      if (a == 1) doa.direction -= 2.0 * doa.direction.dot(normal) * normal;
      doa.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-5;
      driver.on_doa(doa);
    }
    driver.advance_to(t);
  }
  doa::NodeStatus status;
  status.array_id = "A2";
  status.channels.resize(4);
  driver.on_node_status(status);
  const auto swapped = doa::array_flag(doa::ArrayProblem::swapped);
  for (int c = 0; c < 4; ++c) {
    const bool expected = c == 1 || c == 2;
    EXPECT_EQ(
        doa::has_problem(keeper.last.channels[c].array_problems_seen, doa::ArrayProblem::swapped),
        expected)
        << "channel " << c;
    EXPECT_EQ((keeper.last.channels[c].array_problems & swapped) != 0, expected) << c;
  }
  status.array_id = "A1";  // a clean array: untouched
  driver.on_node_status(status);
  for (const auto& channel : keeper.last.channels) EXPECT_EQ(channel.array_problems_seen, 0);

  fusion::MirrorSwapEvent event;
  event.channel_a = 1;
  event.channel_b = 2;
  event.sectors = 5;
  event.time_s = 12.5;
  EXPECT_EQ(
      mirror_swap_warning("A2", 1, 3, event)
          .rfind("A2 channel 1: swapped with channel 2 (input channel 3) (seen by the fusion)", 0),
      0U);
}

TEST(DoaFileReplay, DoaLinesReadBackAsTheMeasurementsWritten) {
  // Two DOAs written out of time order, one with correlated azimuth and elevation errors.
  std::vector<doa::DoaMeasurement> written(2);
  written[0].array_id = "A2";
  written[0].time_s = 3.25;
  written[0].direction = doa::direction_from_azel_deg(120.0, 15.0);
  written[0].azel_covariance_rad2 << 4e-6, -1.2e-6, -1.2e-6, 9e-6;  // correlation -0.2
  written[0].source_index = 1;
  written[0].ambiguity = doa::DoaAmbiguity::mirror_up_down;
  written[1].array_id = "A1";
  written[1].time_s = 3.2;
  written[1].direction = doa::direction_from_azel_deg(-30.0, 40.0);
  written[1].azel_covariance_rad2 = Eigen::Vector2d(1e-6, 2e-6).asDiagonal();
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / "dronetrack_apps_test_doas.jsonl";
  {
    std::ofstream out(file);
    char buffer[1024];
    for (const auto& doa : written) {
      out << std::string(buffer,
                         static_cast<std::size_t>(format_doa_line(doa, buffer, sizeof buffer)))
          << "\n";
    }
  }
  const std::vector<doa::DoaMeasurement> read = read_doa_measurements(file, two_array_site());
  std::filesystem::remove(file);
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].array_id, "A1");  // time order
  EXPECT_EQ(read[0].array_index, 0);
  EXPECT_EQ(read[1].array_index, 1);
  EXPECT_NEAR(read[1].time_s, 3.25, 1e-9);
  EXPECT_LT((read[1].direction - written[0].direction).norm(), 1e-8);
  EXPECT_EQ(read[1].source_index, 1);
  EXPECT_EQ(read[1].ambiguity, doa::DoaAmbiguity::mirror_up_down);
  EXPECT_LT((read[1].azel_covariance_rad2 - written[0].azel_covariance_rad2).norm(), 1e-10);
  EXPECT_LT((read[0].azel_covariance_rad2 - written[1].azel_covariance_rad2).norm(), 1e-10);
}

TEST(DoaFileReplay, FusionAloneTracksASourceTheArraysTriangulate) {
  // A source at (30, 40, 20) m heard by both arrays every 50 ms for 3 s: one confirmed track
  // there, as the replay would make from the same DOAs arriving from its nodes.
  const config::SiteConfig site = two_array_site();
  const Eigen::Vector3d source(30.0, 40.0, 20.0);
  std::vector<doa::DoaMeasurement> doas;
  for (int k = 0; k < 60; ++k) {
    for (int a = 0; a < 2; ++a) {
      doa::DoaMeasurement doa;
      doa.array_id = site.arrays[static_cast<std::size_t>(a)].geometry.id;
      doa.array_index = a;
      doa.time_s = 0.05 * k;
      doa.direction =
          (source - site.arrays[static_cast<std::size_t>(a)].geometry.position_m).normalized();
      doa.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-6;
      doas.push_back(doa);
    }
  }
  class LastTracks : public FusionObserver {
   public:
    void on_tracks(double, const std::vector<fusion::TrackReport>& tracks) override {
      last = tracks;
    }
    std::vector<fusion::TrackReport> last;
  } observer;
  const ReplaySummary summary = replay_doas(site, doas, {&observer});
  EXPECT_EQ(summary.doas, 120);
  EXPECT_EQ(summary.doas_accepted, 120);
  ASSERT_EQ(observer.last.size(), 1u);
  EXPECT_EQ(observer.last[0].status, fusion::TrackStatus::confirmed);
  EXPECT_LT((observer.last[0].position_m - source).norm(), 0.5);
}

}  // namespace
}  // namespace dronetrack::apps
