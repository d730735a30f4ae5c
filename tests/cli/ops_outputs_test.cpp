// Issue 19's operations outputs against the real binary on one short simulated scene:
// /metrics scraped during a real-time `replay --http` and checked against the run's own outputs
// (alert lines, /api/tracks, the summary line) and against the exposition format; a node's
// `--metrics-listen`; `replay --plot` and `eval --plot` pages (one SVG per figure, the track and
// array ids, nothing from the network, every coordinate inside its viewBox); a bad --plot path.
#include <gtest/gtest.h>
#include <httplib.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>

#include "cli_run.hpp"
#include "tests/http_api/exposition_checker.hpp"

namespace {

using namespace dronetrack::cli_test;
using dronetrack::test::check_exposition;
using dronetrack::test::Exposition;
using nlohmann::json;

std::string get(const std::string& url, const std::string& path) {
  static const std::regex host_port(R"(http://([^:/]+):(\d+)/)");
  std::smatch m;
  if (!std::regex_search(url, m, host_port)) return "";
  httplib::Client client(m[1].str(), std::stoi(m[2].str()));
  const auto response = client.Get(path);
  return response && response->status == 200 ? response->body : std::string();
}

// The first http://HOST:PORT/ in `text`, or "".
std::string find_url(const std::string& text) {
  static const std::regex url(R"(http://127\.0\.0\.1:\d+/)");
  std::smatch m;
  return std::regex_search(text, m, url) ? m.str(0) : std::string();
}

std::vector<json> json_lines(const fs::path& file) {
  std::vector<json> out;
  std::istringstream lines(read_text(file));
  std::string line;
  while (std::getline(lines, line)) {
    if (!line.empty()) out.push_back(json::parse(line));
  }
  return out;
}

// Every <svg ...> of a page with its viewBox, and every x/y/cx/cy and path coordinate in it.
struct Svg {
  double width = 0.0;
  double height = 0.0;
  std::vector<std::pair<double, double>> points;
  std::string text;
};

std::vector<Svg> svgs_of(const std::string& html) {
  std::vector<Svg> out;
  std::size_t at = 0;
  while ((at = html.find("<svg", at)) != std::string::npos) {
    const std::size_t end = html.find("</svg>", at);
    if (end == std::string::npos) break;
    Svg svg;
    svg.text = html.substr(at, end - at);
    std::smatch m;
    if (std::regex_search(svg.text, m, std::regex(R"re(viewBox="0 0 ([0-9.]+) ([0-9.]+)")re"))) {
      svg.width = std::stod(m[1]);
      svg.height = std::stod(m[2]);
    }
    static const std::regex attribute_pair(
        R"re((?:cx|x1|x2|x)="(-?[0-9.]+)" (?:cy|y1|y2|y)="(-?[0-9.]+)")re");
    static const std::regex path_pair(R"([ML](-?[0-9.]+) (-?[0-9.]+))");
    for (const auto* pattern : {&attribute_pair, &path_pair}) {
      for (auto it = std::sregex_iterator(svg.text.begin(), svg.text.end(), *pattern);
           it != std::sregex_iterator(); ++it) {
        svg.points.push_back({std::stod((*it)[1]), std::stod((*it)[2])});
      }
    }
    out.push_back(std::move(svg));
    at = end;
  }
  return out;
}

void expect_self_contained(const std::string& html, std::size_t figures) {
  const auto svgs = svgs_of(html);
  EXPECT_EQ(svgs.size(), figures);
  EXPECT_EQ(html.find("http://"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find(" src="), std::string::npos);
  EXPECT_EQ(html.find(" href="), std::string::npos);
  for (const auto& svg : svgs) {
    ASSERT_GT(svg.width, 0.0);
    EXPECT_GT(svg.points.size(), 10u);
    for (const auto& [x, y] : svg.points) {
      EXPECT_TRUE(x >= 0.0 && x <= svg.width && y >= 0.0 && y <= svg.height)
          << "(" << x << ", " << y << ") outside the viewBox";
    }
  }
}

class OpsOutputs : public ::testing::Test {
 protected:
  // One scene and one real-time replay serving /metrics, scraped mid-run and once its outputs
  // are in place, then stopped with SIGINT.
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("dronetrack_ops_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const Outcome sim = run(
        {"sim", std::string(DRONETRACK_SOURCE_DIR) + "/config/scenarios/perimeter-two-drones.json",
         "--out", (dir_ / "scene").string(), "--duration-s", "4"},
        dir_);
    ASSERT_EQ(sim.exit_code, 0) << sim.err;
    RunOptions options;
    options.timeout = 60s;
    options.signal = SIGINT;
    options.signal_when = [] {
      const std::string url = find_url(read_text(dir_ / "run.out"));
      if (!url.empty() && mid_run_.empty()) mid_run_ = get(url, "/metrics");
      return fs::exists(dir_ / "tracks.jsonl");
    };
    options.while_running = [] {
      const std::string url = find_url(read_text(dir_ / "run.out"));
      final_ = get(url, "/metrics");
      api_tracks_ = get(url, "/api/tracks");
    };
    replay_ = run({"replay", (dir_ / "scene/site.json").string(), "--realtime", "--http",
                   "127.0.0.1:0", "--tracks-out", (dir_ / "tracks.jsonl").string(), "--doa-out",
                   (dir_ / "doa.jsonl").string(), "--alerts-out", (dir_ / "alerts.jsonl").string(),
                   "--plot", (dir_ / "replay.html").string()},
                  dir_, options);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static inline fs::path dir_;
  static inline Outcome replay_;
  static inline std::string mid_run_;
  static inline std::string final_;
  static inline std::string api_tracks_;
};

TEST_F(OpsOutputs, MetricsAreValidExpositionMidRunAndAtTheEnd) {
  ASSERT_EQ(replay_.exit_code, 130) << replay_.err;
  ASSERT_FALSE(mid_run_.empty());
  ASSERT_FALSE(final_.empty());
  for (const std::string* body : {&mid_run_, &final_}) {
    const Exposition parsed = check_exposition(*body);
    EXPECT_TRUE(parsed.ok()) << parsed.problems.front();
    EXPECT_EQ(
        parsed.value("dronetrack_build_info{version=\"" DRONETRACK_VERSION "\",role=\"replay\"}"),
        1.0);
  }
}

TEST_F(OpsOutputs, MetricsMatchTheRunsOwnOutputs) {
  const Exposition metrics = check_exposition(final_);
  ASSERT_TRUE(metrics.ok());
  // Alerts: one per alert line, by event.
  std::map<std::string, int> alert_lines;
  for (const auto& line : json_lines(dir_ / "alerts.jsonl")) ++alert_lines[line["event"]];
  for (const char* event : {"entered", "left", "class_changed"}) {
    EXPECT_EQ(metrics.value(std::string("dronetrack_alerts_total{event=\"") + event + "\"}"),
              alert_lines[event])
        << event;
  }
  // Tracks by status and class: /api/tracks at the same (last) tick.
  std::map<std::string, int> by_status_class;
  const json api = json::parse(api_tracks_);
  for (const auto& track : api["tracks"]) {
    ++by_status_class["{status=\"" + track["status"].get<std::string>() + "\",class=\"" +
                      track["class"].get<std::string>() + "\"}"];
  }
  int tracks = 0;
  for (const char* status : {"tentative", "confirmed", "coasting"}) {
    for (const char* cls : {"unknown", "drone", "ground", "aircraft"}) {
      const std::string labels = std::string("{status=\"") + status + "\",class=\"" + cls + "\"}";
      EXPECT_EQ(metrics.value("dronetrack_tracks" + labels), by_status_class[labels]) << labels;
      tracks += by_status_class[labels];
    }
  }
  EXPECT_EQ(metrics.sum("dronetrack_tracks"), tracks);
  // The summary line: "N DOAs (M accepted), K track ticks".
  std::smatch m;
  ASSERT_TRUE(std::regex_search(replay_.err, m,
                                std::regex(R"((\d+) DOAs \((\d+) accepted\), (\d+) track ticks)")));
  EXPECT_EQ(metrics.sum("dronetrack_fusion_doas_total"), std::stod(m[1]));
  EXPECT_EQ(metrics.value("dronetrack_fusion_doas_total{verdict=\"accepted\"}"), std::stod(m[2]));
  EXPECT_EQ(metrics.value("dronetrack_fusion_ticks_total"), std::stod(m[3]));
  EXPECT_GT(std::stod(m[2]), 100.0);
  // Paced: every tick has a latency, at least the reorder window behind the audio, but for
  // those of the audio's last 0.2 s (0.1 s apart), reported when the recordings end.
  EXPECT_EQ(metrics.value("dronetrack_track_latency_seconds_count"), std::stod(m[3]));
  EXPECT_LE(metrics.value("dronetrack_track_latency_seconds_bucket{le=\"0.2\"}"), 3.0);
  EXPECT_LT(metrics.value("dronetrack_track_latency_seconds_bucket{le=\"0.2\"}"),
            metrics.value("dronetrack_track_latency_seconds_bucket{le=\"0.5\"}"));
  // Each array reported, with clean audio.
  for (const char* array : {"N1", "N2", "N3", "N4"}) {
    EXPECT_EQ(metrics.value(std::string("dronetrack_node_clipped_samples_total{array=\"") + array +
                            "\"}"),
              0.0)
        << array;
  }
  // The tracks file agrees with the engine on how many tracks were confirmed at least.
  std::set<int> ids;
  for (const auto& line : json_lines(dir_ / "tracks.jsonl")) {
    if (line["status"] == "confirmed") ids.insert(line["id"].get<int>());
  }
  EXPECT_GE(metrics.value("dronetrack_fusion_track_events_total{event=\"confirmed\"}"),
            static_cast<double>(ids.size()));
  // Duplicates pruned are among the deleted (NaN, absent, fails both).
  EXPECT_GE(metrics.value("dronetrack_fusion_track_events_total{event=\"duplicate_pruned\"}"), 0.0);
  EXPECT_LE(metrics.value("dronetrack_fusion_track_events_total{event=\"duplicate_pruned\"}"),
            metrics.value("dronetrack_fusion_track_events_total{event=\"deleted\"}"));
}

TEST_F(OpsOutputs, ReplayPlotDrawsEveryTrackAndArray) {
  const std::string html = read_text(dir_ / "replay.html");
  expect_self_contained(html, 4);  // plan view, altitude, DOA azimuth, DOA elevation
  std::set<int> ids;
  for (const auto& line : json_lines(dir_ / "tracks.jsonl")) ids.insert(line["id"].get<int>());
  ASSERT_FALSE(ids.empty());
  for (int id : ids) EXPECT_NE(html.find(">track " + std::to_string(id) + "<"), std::string::npos);
  for (const char* array : {"N1", "N2", "N3", "N4"})
    EXPECT_NE(html.find(std::string(">array ") + array + "<"), std::string::npos) << array;
}

TEST_F(OpsOutputs, EvalPlotDrawsTracksTruthAndErrors) {
  const fs::path page = dir_ / "eval.html";
  const Outcome eval = run({"eval", "--truth", (dir_ / "scene/truth.json").string(), "--tracks",
                            (dir_ / "tracks.jsonl").string(), "--doa",
                            (dir_ / "doa.jsonl").string(), "--plot", page.string()},
                           dir_);
  ASSERT_EQ(eval.exit_code, 0) << eval.err;
  const std::string html = read_text(page);
  expect_self_contained(html, 4);  // plan view, altitude, 3-D error, DOA error
  for (const char* truth : {">truth D1<", ">truth D2<", ">array N1<", ">array N4<"})
    EXPECT_NE(html.find(truth), std::string::npos) << truth;
  EXPECT_TRUE(std::regex_search(html, std::regex(">D1: track [0-9]+<")));
  for (const auto& entry : fs::directory_iterator(dir_))  // written atomically: no temporary
    EXPECT_EQ(entry.path().filename().string().find(".eval.html"), std::string::npos);
}

TEST_F(OpsOutputs, BadPlotPathIsOneErrorLine) {
  const Outcome eval =
      run({"eval", "--truth", (dir_ / "scene/truth.json").string(), "--tracks",
           (dir_ / "tracks.jsonl").string(), "--plot", (dir_ / "no/such/dir/report.html").string()},
          dir_);
  EXPECT_EQ(eval.exit_code, 1);
  EXPECT_EQ(std::count(eval.err.begin(), eval.err.end(), '\n'), 1) << eval.err;
  EXPECT_NE(eval.err.find("report.html"), std::string::npos) << eval.err;
  EXPECT_TRUE(eval.out.empty()) << "nothing printed before the refusal";
}

TEST_F(OpsOutputs, NodeServesItsOwnMetrics) {
  setenv(
      "CYCLONEDDS_URI",
      ("file://" + std::string(DRONETRACK_SOURCE_DIR) + "/config/cyclonedds-loopback.xml").c_str(),
      1);
  std::string body;
  RunOptions options;
  options.timeout = 30s;
  options.signal = SIGINT;
  options.signal_when = [&] {
    const std::string url = find_url(read_text(dir_ / "run.err"));
    if (url.empty()) return false;
    body = get(url, "/metrics");
    return body.find("dronetrack_node_frames_total{array=\"N2\"} 0\n") == std::string::npos &&
           !body.empty();
  };
  const Outcome node = run({"node", (dir_ / "scene/site.json").string(), "--array", "N2",
                            "--realtime", "--domain", "211", "--metrics-listen", "127.0.0.1:0"},
                           dir_, options);
  EXPECT_EQ(node.exit_code, 130) << node.err;
  const Exposition metrics = check_exposition(body);
  ASSERT_TRUE(metrics.ok()) << (metrics.problems.empty() ? body : metrics.problems.front());
  EXPECT_EQ(
      metrics.value("dronetrack_build_info{version=\"" DRONETRACK_VERSION "\",role=\"node\"}"),
      1.0);
  EXPECT_GT(metrics.value("dronetrack_node_frames_total{array=\"N2\"}"), 0.0);
  EXPECT_EQ(metrics.value("dronetrack_node_overruns_total{array=\"N2\"}"), 0.0);
  EXPECT_EQ(metrics.value("dronetrack_node_rejects_total{array=\"N2\",reason=\"bad_block\"}"), 0.0);
  // Published so far never exceeds what the node says it published in the end.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(node.err, m, std::regex(R"((\d+) DOAs published)")));
  EXPECT_LE(metrics.value("dronetrack_node_doas_published_total{array=\"N2\"}"), std::stod(m[1]));
}

}  // namespace
