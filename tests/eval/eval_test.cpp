#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <unistd.h>

#include <functional>

#include <gtest/gtest.h>

#include "eval/metrics.hpp"
#include "eval/readers.hpp"
#include "eval/report.hpp"

namespace dronetrack::eval {
namespace {

// A source moving along x at 2 m/s from (10, 0, 20), 100 Hz for `duration_s`.
TruthSource moving_source(const std::string& id, Eigen::Vector3d start, Eigen::Vector3d velocity,
                          double duration_s) {
  TruthSource source;
  source.id = id;
  for (int i = 0; i <= static_cast<int>(std::lround(duration_s * 100)); ++i) {
    const double t = i * 0.01;
    source.time_s.push_back(t);
    source.position_m.push_back(start + velocity * t);
    source.direction_by_array["A1"].push_back((start + velocity * t).normalized());
  }
  return source;
}

std::vector<TrackRecord> follow(const TruthSource& source, int id, Eigen::Vector3d offset,
                                double from_s, double to_s) {
  std::vector<TrackRecord> out;
  for (int k = static_cast<int>(std::lround(from_s * 10)); k <= std::lround(to_s * 10); ++k) {
    const double t = k * 0.1;
    out.push_back({t, id, source.position_at(t) + offset, "confirmed"});
  }
  return out;
}

TEST(EvalMetrics, KnownOffsetGivesKnownErrors) {
  Truth truth;
  truth.sources.push_back(moving_source("D1", {10, 0, 20}, {2, 0, 0}, 10.0));
  const auto tracks = follow(truth.sources[0], 7, {0.3, 0.4, 1.2}, 0.0, 10.0);  // |e| = 1.3
  const EvalReport report = evaluate(truth, tracks, {}, EvalOptions{});
  EXPECT_NEAR(report.tick_s, 0.1, 1e-9);
  EXPECT_EQ(report.position.samples, 101);
  EXPECT_NEAR(report.position.rmse_3d_m, 1.3, 1e-9);
  EXPECT_NEAR(report.position.median_error_m, 1.3, 1e-9);
  EXPECT_NEAR(report.position.rmse_horizontal_m, 0.5, 1e-9);
  EXPECT_NEAR(report.position.rmse_vertical_m, 1.2, 1e-9);
  EXPECT_NEAR(report.coverage, 1.0, 1e-9);
  EXPECT_EQ(report.id_switches, 0);
  EXPECT_NEAR(report.false_track_fraction, 0.0, 1e-12);
  ASSERT_EQ(report.sources.size(), 1u);
  EXPECT_EQ(report.sources[0].track_ids, std::vector<int>{7});
  // The series behind the figures (plots): one error per tick, the same 1.3 m, track 7.
  ASSERT_EQ(report.sources[0].errors.size(), 101u);
  EXPECT_NEAR(report.sources[0].errors[50].time_s, 5.0, 1e-9);
  EXPECT_NEAR(report.sources[0].errors[50].error_m, 1.3, 1e-9);
  EXPECT_EQ(report.sources[0].errors[50].track_id, 7);
}

// The tick is the tracks' step, a difference of times as read (59.9 - 59.8 is 0.1 + 1.4e-15), so
// the 601st tick lands a few ulps past the truth's last sample at 60 s. It is still that sample,
// and a track reported there follows the source, not nothing.
TEST(EvalMetrics, TheLastTickIsWithinTheTruthDespiteRounding) {
  Truth truth;
  truth.sources.push_back(moving_source("D1", {10, 0, 20}, {2, 0, 0}, 60.0));
  EvalOptions options;
  options.tick_s = 59.9 - 59.8;
  ASSERT_GT(600 * options.tick_s, truth.sources[0].time_s.back());
  const auto tracks = follow(truth.sources[0], 3, {0.3, 0.4, 0.0}, 0.0, 60.0);
  const EvalReport report = evaluate(truth, tracks, {}, options);
  EXPECT_EQ(report.position.samples, 601);
  EXPECT_NEAR(report.coverage, 1.0, 1e-9);
  EXPECT_NEAR(report.false_track_time_s, 0.0, 1e-12);
}

TEST(EvalMetrics, PercentageFitErrorRelativeToArrayCentroid) {
  Truth truth;
  TruthSource hover;
  hover.id = "D1";
  hover.time_s = {0.0, 1.0};
  hover.position_m = {{30, 5, 0}, {30, 5, 0}};
  truth.sources.push_back(hover);
  truth.array_centres_m = {{"A1", {0, 5, 0}}, {"A2", {20, 5, 0}}};  // centroid (10, 5, 0)
  // Truth relative to the centroid: (20, 0, 0); the estimate is 1 m off in x and 1 m in z.
  const std::vector<TrackRecord> tracks{{0.0, 1, {31, 5, 1}, "confirmed"},
                                        {0.5, 1, {31, 5, 1}, "confirmed"},
                                        {1.0, 1, {31, 5, 1}, "confirmed"}};
  const EvalReport report = evaluate(truth, tracks, {}, EvalOptions{});
  EXPECT_NEAR(report.position.pfe_total_percent, 100.0 * std::sqrt(2.0) / 20.0, 1e-9);
  EXPECT_NEAR(report.position.pfe_axis_percent.x(), 5.0, 1e-9);
  // y and z of the truth are 0 relative to the centroid: no sample defines their ratio.
  EXPECT_NEAR(report.position.pfe_axis_percent.y(), 0.0, 1e-12);
}

TEST(EvalMetrics, CoverageIdSwitchesAndFalseTracks) {
  Truth truth;
  truth.sources.push_back(moving_source("D1", {10, 0, 20}, {2, 0, 0}, 10.0));
  // Covered by id 1 until 4 s, nothing until 5 s, then id 2; and a false track for 2 s.
  auto tracks = follow(truth.sources[0], 1, {0.5, 0, 0}, 0.0, 3.9);
  const auto later = follow(truth.sources[0], 2, {0.5, 0, 0}, 5.0, 10.0);
  tracks.insert(tracks.end(), later.begin(), later.end());
  for (int k = 0; k < 20; ++k) tracks.push_back({k * 0.1, 9, {500, 500, 50}, "confirmed"});
  // Tentative lines are not tracks unless asked for.
  for (int k = 40; k < 50; ++k) tracks.push_back({k * 0.1, 4, {18, 0, 20}, "tentative"});
  const EvalReport report = evaluate(truth, tracks, {}, EvalOptions{});
  EXPECT_NEAR(report.coverage, 91.0 / 101.0, 1e-9);
  EXPECT_EQ(report.id_switches, 1);
  EXPECT_EQ(report.tracks_seen, 3);
  EXPECT_NEAR(report.false_track_time_s, 2.0, 1e-9);
  EXPECT_NEAR(report.false_track_fraction, 20.0 / (91.0 + 20.0), 1e-9);
  EXPECT_EQ(report.sources[0].track_ids, (std::vector<int>{1, 2}));
  // Near no source at all: the whole false track is a ghost...
  EXPECT_NEAR(report.ghost_track_time_s, 2.0, 1e-9);
  EXPECT_NEAR(report.ghost_track_fraction, 20.0 / (91.0 + 20.0), 1e-9);
  // ... until a real non-drone source (an aircraft) is where it is: still a false track (it
  // follows no drone), no longer a ghost.
  Truth with_aircraft = truth;
  with_aircraft.others.push_back(moving_source("P1", {500, 500, 50}, {0, 0, 0}, 10.0));
  with_aircraft.other_classes.push_back("aircraft");
  const EvalReport on_aircraft = evaluate(with_aircraft, tracks, {}, EvalOptions{});
  EXPECT_NEAR(on_aircraft.false_track_time_s, 2.0, 1e-9);
  EXPECT_NEAR(on_aircraft.ghost_track_time_s, 0.0, 1e-12);
  EXPECT_NEAR(on_aircraft.others[0].tracked_time_s, 2.0, 1e-9);

  EvalOptions tentative;
  tentative.include_tentative = true;
  const EvalReport with_tentative = evaluate(truth, tracks, {}, tentative);
  EXPECT_NEAR(with_tentative.coverage, 1.0, 1e-9);
  EXPECT_EQ(with_tentative.id_switches, 2);  // 1 -> 4 -> 2
}

TEST(EvalMetrics, AssignmentKeepsCrossingSourcesApart) {
  Truth truth;
  truth.sources.push_back(moving_source("D1", {-20, 0, 20}, {4, 0, 0}, 10.0));
  truth.sources.push_back(moving_source("D2", {20, 0.5, 20}, {-4, 0, 0}, 10.0));
  auto tracks = follow(truth.sources[0], 1, {0, 0.2, 0}, 0.0, 10.0);
  const auto second = follow(truth.sources[1], 2, {0, 0.2, 0}, 0.0, 10.0);
  tracks.insert(tracks.end(), second.begin(), second.end());
  const EvalReport report = evaluate(truth, tracks, {}, EvalOptions{});
  EXPECT_EQ(report.id_switches, 0);
  EXPECT_NEAR(report.position.rmse_3d_m, 0.2, 1e-9);
  EXPECT_NEAR(report.coverage, 1.0, 1e-9);
}

TEST(EvalMetrics, DoaErrorAgainstTheNearestSource) {
  Truth truth;
  truth.sources.push_back(moving_source("D1", {50, 0, 0}, {0, 0, 0}, 2.0));
  truth.sources.push_back(moving_source("D2", {0, 50, 0}, {0, 0, 0}, 2.0));
  std::vector<DoaRecord> doas;
  const auto add = [&doas](double time_s, const char* array, const Eigen::Vector3d& direction) {
    DoaRecord record;
    record.time_s = time_s;
    record.array = array;
    record.direction = direction;
    doas.push_back(record);
  };
  const double two_deg = 2.0 * M_PI / 180.0;
  for (int k = 0; k < 10; ++k) {
    add(k * 0.1, "A1", {std::cos(two_deg), std::sin(two_deg), 0});          // D1 + 2 deg
    add(k * 0.1, "A1", {std::sin(two_deg * 2), std::cos(two_deg * 2), 0});  // D2 - 4
  }
  add(0.5, "A9", {1, 0, 0});  // no truth for this array
  int unmatched = 0;
  const auto metrics = doa_errors(truth, doas, &unmatched);
  ASSERT_EQ(metrics.size(), 1u);
  EXPECT_EQ(metrics[0].count, 20);
  EXPECT_NEAR(metrics[0].mean_error_deg, 3.0, 1e-9);
  EXPECT_NEAR(metrics[0].p90_error_deg, 4.0, 1e-9);
  EXPECT_EQ(unmatched, 1);
  // Each matched DOA's error with its time, in input order (plots).
  ASSERT_EQ(metrics[0].time_s.size(), 20u);
  ASSERT_EQ(metrics[0].error_deg.size(), 20u);
  EXPECT_NEAR(metrics[0].time_s[2], 0.1, 1e-12);
  EXPECT_NEAR(metrics[0].error_deg[0], 2.0, 1e-9);
  EXPECT_NEAR(metrics[0].error_deg[1], 4.0, 1e-9);
}

// A static source whose track starts 8 m off and closes in at 1 m/s: converged once within the
// gate for good (a later excursion resets it); the final error is the last tick's.
TEST(EvalMetrics, FinalErrorAndTimeToConvergeOfAStaticSource) {
  Truth truth;
  truth.sources.push_back(moving_source("S1", {40, 10, -5}, {0, 0, 0}, 20.0));
  std::vector<TrackRecord> tracks;
  for (int k = 0; k <= 200; ++k) {
    const double t = k * 0.1;
    double error_m = std::max(0.5, 8.0 - t);  // within 3 m from t = 5 s
    if (k == 80) error_m = 4.0;               // one excursion at 8 s: converged from 8.1 s
    tracks.push_back(
        {t, 1, truth.sources[0].position_at(t) + Eigen::Vector3d(0, error_m, 0), "confirmed"});
  }
  const EvalReport report = evaluate(truth, tracks, {}, EvalOptions{});
  ASSERT_EQ(report.sources.size(), 1u);
  EXPECT_NEAR(report.sources[0].final_error_m, 0.5, 1e-9);
  EXPECT_NEAR(report.sources[0].converged_after_s, 8.1, 1e-9);
  EXPECT_NEAR(report.sources[0].travelled_m, 0.0, 1e-9);
  EvalOptions loose;
  loose.converge_gate_m = 10.0;
  EXPECT_NEAR(evaluate(truth, tracks, {}, loose).sources[0].converged_after_s, 0.0, 1e-9);
  // Never within 0.1 m: never converged.
  EvalOptions tight;
  tight.converge_gate_m = 0.1;
  EXPECT_EQ(evaluate(truth, tracks, {}, tight).sources[0].converged_after_s, -1.0);
  // A moving source's path length is reported (20 s at 2 m/s).
  Truth moving;
  moving.sources.push_back(moving_source("D1", {10, 0, 20}, {2, 0, 0}, 20.0));
  EXPECT_NEAR(evaluate(moving, follow(moving.sources[0], 1, {0, 0, 0}, 0.0, 20.0), {}, {})
                  .sources[0]
                  .travelled_m,
              40.0, 1e-6);
}

// A one-array track on the source's bearing with a range error its stated extent covers is the
// source's track (associated, covering); off the bearing, or claiming more than it knows, it is
// a false track.
TEST(EvalMetrics, OneArrayTrackCoversOnItsBearingWithinItsStatedExtent) {
  Truth truth;
  truth.sources.push_back(moving_source("D1", {300, 0, 60}, {0, 0, 0}, 10.0));
  truth.array_centres_m = {{"A1", {0, 0, 0}}};
  const auto track_at = [&](double range_scale, double angle_deg, double std_m) {
    std::vector<TrackRecord> tracks;
    const double angle = angle_deg * M_PI / 180.0;
    const Eigen::Vector3d truth_position(300, 0, 60);
    const Eigen::Vector3d along = truth_position * range_scale;
    const Eigen::Vector3d turned(along.x() * std::cos(angle) - along.y() * std::sin(angle),
                                 along.x() * std::sin(angle) + along.y() * std::cos(angle),
                                 along.z());
    for (int k = 0; k <= 100; ++k) {
      TrackRecord record{k * 0.1, 4, turned, "confirmed"};
      record.one_array = true;
      record.position_std_m = Eigen::Vector3d(std_m, std_m, std_m);
      tracks.push_back(record);
    }
    return evaluate(truth, tracks, {}, EvalOptions{});
  };
  // 60 m short along the ray (0.8 of the range), 40 m std each axis: on the bearing, inside.
  const EvalReport on_bearing = track_at(0.8, 0.0, 40.0);
  EXPECT_NEAR(on_bearing.coverage, 1.0, 1e-9);
  EXPECT_NEAR(on_bearing.false_track_fraction, 0.0, 1e-12);
  EXPECT_NEAR(on_bearing.sources[0].one_array_time_s, 10.1, 1e-9);
  EXPECT_NEAR(on_bearing.sources[0].first_tracked_s, 0.0, 1e-9);
  // The same error claimed at 10 m std: the truth is outside what the track says: false.
  EXPECT_NEAR(track_at(0.8, 0.0, 10.0).coverage, 0.0, 1e-12);
  // 5 deg off the bearing: false however wide.
  EXPECT_NEAR(track_at(1.0, 5.0, 100.0).false_track_fraction, 1.0, 1e-12);
}

// A cone DOA is judged on the one angle it measured; a mirror DOA against the nearer image.
TEST(EvalMetrics, ConeAndMirrorDoaErrors) {
  Truth truth;
  truth.sources.push_back(moving_source("S1", {30, 40, 0}, {0, 0, 0}, 1.0));  // (0.6, 0.8, 0)
  DoaRecord cone;
  cone.time_s = 0.5;
  cone.array = "A1";
  cone.ambiguity = "cone";
  cone.direction = {1, 0, 0};  // a display point of the cone, not the source
  cone.cone = DoaRecord::Cone{};
  cone.cone->axis = {1, 0, 0};
  cone.cone->angle_deg = std::acos(0.6) * 180.0 / M_PI + 1.5;
  DoaRecord mirror;
  mirror.time_s = 0.5;
  mirror.array = "A1";
  mirror.ambiguity = "mirror_up_down";
  mirror.mirror_normal = Eigen::Vector3d(0, 0, 1);
  mirror.direction = Eigen::Vector3d(0.6, 0.8, 0.0);
  const auto metrics = doa_errors(truth, {cone}, nullptr);
  ASSERT_EQ(metrics.size(), 1u);
  EXPECT_NEAR(metrics[0].mean_error_deg, 1.5, 1e-6);
  EXPECT_NEAR(doa_errors(truth, {mirror}, nullptr)[0].mean_error_deg, 0.0, 1e-6);
  // A source below the plane (z = -10 m at 50 m): the reported upper image is its mirror.
  Truth below;
  below.sources.push_back(moving_source("S2", {30, 40, -10}, {0, 0, 0}, 1.0));
  mirror.direction = Eigen::Vector3d(30, 40, 10).normalized();
  EXPECT_NEAR(doa_errors(below, {mirror}, nullptr)[0].mean_error_deg, 0.0, 1e-6);
  DoaRecord plain = mirror;
  plain.mirror_normal.reset();
  EXPECT_GT(doa_errors(below, {plain}, nullptr)[0].mean_error_deg, 20.0);
}

std::string expect_input_error(const std::function<void()>& action) {
  try {
    action();
  } catch (const InputError& error) {
    return error.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

TEST(EvalReaders, ReadsTheDocumentedShapes) {
  const Truth truth = parse_truth(R"({"sources": [{"id": "D1", "kind": "drone", "t": [0, 0.01],
      "position_m": [[1,2,3],[1,2,4]], "velocity_mps": [[0,0,0],[0,0,0]],
      "doa": {"A1": {"direction": [[1,0,0],[0,1,0]]}}}], "interferers": [],
      "arrays": {"A1": {"centre_m": [0,0,2], "recording_end_s": 30}}})",
                                  "truth.json");
  ASSERT_EQ(truth.sources.size(), 1u);
  EXPECT_NEAR(truth.sources[0].position_at(0.005).z(), 3.5, 1e-12);
  EXPECT_EQ(truth.recording_end_s.value_or(0), 30.0);
  const auto tracks = parse_tracks(
      "{\"t\": 1.5, \"id\": 3, \"position_m\": [1,2,3], \"velocity_mps\": [0,0,0], "
      "\"acceleration_mps2\": [0,0,0], \"position_std_m\": [1,1,1], \"status\": \"coasting\"}\n\n",
      "T.jsonl");
  ASSERT_EQ(tracks.size(), 1u);
  EXPECT_EQ(tracks[0].id, 3);
  EXPECT_EQ(tracks[0].status, "coasting");
  const auto doas = parse_doas(
      "{\"t\": 1.5, \"array\": \"A1\", \"direction\": [0,0,1], \"azimuth_deg\": 0, "
      "\"elevation_deg\": 90, \"quality\": 0.5}\n",
      "D.jsonl");
  ASSERT_EQ(doas.size(), 1u);
  EXPECT_EQ(doas[0].array, "A1");
}

// A cone DOA must say what it measured, and only a cone may carry a cone.
TEST(EvalReaders, ConeAndMirrorBlocksAreChecked) {
  const std::string head = R"({"t": 1, "array": "H1", "direction": [1,0,0], )";
  EXPECT_NE(expect_input_error([&] {
              parse_doas(head + R"("ambiguity": "cone"})", "D.jsonl");
            }).find("D.jsonl:1: cone: a cone DOA must say what it measured"),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_doas(head + R"("ambiguity": "cone", "cone": {"axis": [1,1,0], )"
                                R"("angle_deg": 30, "angle_std_deg": 1}})",
                         "D.jsonl");
            }).find("D.jsonl:1: cone.axis: expected a unit vector"),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_doas(head + R"("ambiguity": "cone", "cone": {"axis": [1,0,0], )"
                                R"("angle_deg": 30, "angle_std_deg": 1, "peaks_deg": [30, 40], )"
                                R"("peak_weights": [1]}})",
                         "D.jsonl");
            }).find("D.jsonl:1: cone.peaks_deg: expected up to 4 angles"),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_doas(head + R"("ambiguity": "cone", "cone": {"axis": [1,0,0], )"
                                R"("angle_deg": 190, "angle_std_deg": 1}})",
                         "D.jsonl");
            }).find("D.jsonl:1: cone.angle_deg"),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_doas(head + R"("mirror_normal": [0,0,1]})", "D.jsonl");
            }).find("D.jsonl:1: mirror_normal: only a mirror_up_down DOA carries one"),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_doas(head + R"("pose": {"centre_m": [1,2,3], "attitude_deg": [0, 0]}})",
                         "D.jsonl");
            }).find("D.jsonl:1: pose.attitude_deg: expected 3 numbers"),
            std::string::npos);
}

TEST(EvalReaders, BadInputNamesFileLineAndKey) {
  const std::string good =
      "{\"t\": 1, \"id\": 1, \"position_m\": [1,2,3], \"status\": \"confirmed\"}\n";
  EXPECT_EQ(expect_input_error([&] {
              parse_tracks(good + good + "{\"t\": 1, \"id\": 1, \"position_m\": [1,2]}\n",
                           "T.jsonl");
            }),
            "T.jsonl:3: position_m: expected 3 numbers, got a list of 2");
  EXPECT_NE(expect_input_error([&] {
              parse_tracks(good + "{\"t\": 1,\n", "T.jsonl");
            }).find("T.jsonl:2: invalid JSON"),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_tracks("{\"t\": 1, \"id\": 1, \"position_m\": [1,2,3], \"status\": \"lost\"}",
                           "T.jsonl");
            }).find("T.jsonl:1: status: unknown value \"lost\""),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_doas("{\"t\": 1, \"direction\": [1,0,0]}", "D.jsonl");
            }).find("D.jsonl:1: array: required string is missing"),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_truth(R"({"sources": [{"id": "D1", "t": [0, 1, 2],
                  "position_m": [[1,2,3],[1,2,4]]}]})",
                          "truth.json");
            }).find("truth.json: sources[0].position_m: has 2 rows but t has 3"),
            std::string::npos);
  EXPECT_NE(expect_input_error([&] {
              parse_truth(R"({"sources": [{"id": "D1", "t": [0, 1, 1],
                  "position_m": [[1,2,3],[1,2,4],[1,2,5]]}]})",
                          "truth.json");
            }).find("truth.json: sources[0].t[2]: times must be increasing"),
            std::string::npos);
  EXPECT_NE(expect_input_error([] {
              parse_truth("{\n\"sources\": [}", "truth.json");
            }).find("truth.json:2: invalid JSON"),
            std::string::npos);
}

TEST(EvalReport, TableAndJsonCarryTheFigures) {
  Truth truth;
  truth.sources.push_back(moving_source("D1", {10, 0, 20}, {2, 0, 0}, 2.0));
  const auto tracks = follow(truth.sources[0], 7, {0, 0, 1}, 0.0, 2.0);
  const EvalReport report = evaluate(truth, tracks, {}, EvalOptions{});
  const std::string table = format_table(report);
  EXPECT_NE(table.find("D1"), std::string::npos);
  EXPECT_NE(table.find("100.00%"), std::string::npos);
  const auto json = to_json(report);
  EXPECT_NEAR(json["position"]["rmse_3d_m"].get<double>(), 1.0, 1e-9);
  EXPECT_EQ(json["sources"][0]["track_ids"][0].get<int>(), 7);
  EXPECT_TRUE(json.contains("ghost_track_time_s") && json.contains("ghost_track_fraction"));
}

// The command end to end: files in, table out; a bad file is one line and exit 1.
TEST(EvalCommand, RunsOnFilesAndRejectsBadOnes) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("dronetrack_eval_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  {
    std::ofstream truth(dir / "truth.json");
    truth
        << R"({"sources": [{"id": "D1", "t": [0, 1, 2], "position_m": [[0,0,10],[1,0,10],[2,0,10]],
                "doa": {"A1": {"direction": [[0,0,1],[0,0,1],[0,0,1]]}}}]})";
    std::ofstream tracks(dir / "tracks.jsonl");
    for (int k = 0; k <= 20; ++k) {
      tracks << "{\"t\": " << k * 0.1 << ", \"id\": 1, \"position_m\": [" << k * 0.1
             << ", 0, 11], \"status\": \"confirmed\"}\n";
    }
    std::ofstream bad(dir / "bad.jsonl");
    bad << "{\"t\": 0, \"id\": 1, \"position_m\": [0, 0, 10], \"status\": \"confirmed\"}\n"
        << "{\"t\": 0.1, \"id\": \"one\", \"position_m\": [0, 0, 10]}\n";
  }
  const std::string binary = DRONETRACK_BINARY;
  const std::string base = binary + " eval --truth " + (dir / "truth.json").string();
  const std::string json_path = (dir / "report.json").string();
  EXPECT_EQ(std::system((base + " --tracks " + (dir / "tracks.jsonl").string() + " --json " +
                         json_path + " > " + (dir / "out.txt").string())
                            .c_str()),
            0);
  std::ifstream report_file(json_path);
  std::stringstream report_text;
  report_text << report_file.rdbuf();
  const auto json = nlohmann::json::parse(report_text.str());
  EXPECT_NEAR(json["position"]["rmse_3d_m"].get<double>(), 1.0, 1e-9);
  const int status = std::system((base + " --tracks " + (dir / "bad.jsonl").string() + " 2> " +
                                  (dir / "err.txt").string() + " > /dev/null")
                                     .c_str());
  EXPECT_NE(status, 0);
  std::ifstream error_file(dir / "err.txt");
  std::string first_line;
  std::getline(error_file, first_line);
  EXPECT_NE(first_line.find("bad.jsonl:2: id"), std::string::npos) << first_line;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace dronetrack::eval
