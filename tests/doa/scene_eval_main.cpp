// doa_scene_eval SCENARIO.json [--audible-snr-db DB] [--static-null 0|1] [--audibility]
// [TRACKER ...]: renders a simulated scene in memory, runs every array's NodePipeline with each
// TDOA tracker (default: all four) and prints the accuracy table (markdown rows) that
// docs/doa.md quotes; --audibility adds each drone's frames heard by each audibility rule and the
// DOA coverage over them; --breakdown (implies --audibility) each missed comb-audible frame's
// cause in pipeline order (docs/doa.md "Where the drones' frames go"); --follow 0|1 sets
// doa.follow_source_tracks; --comb-look 0|1 doa.comb_look; --frames ARRAY FROM_S TO_S prints
// that array's frames in the window as the node's trace saw them (looks, candidates, truth).
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "doa/tdoa_tracker.hpp"
#include "sim/scenario.hpp"
#include "tests/doa/scene_eval.hpp"

int main(int argc, char** argv) {
  using namespace dronetrack;
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: doa_scene_eval SCENARIO.json [--audible-snr-db DB] [--static-null 0|1] "
                 "[--static-cancel 0|1] "
                 "[--audibility] [--breakdown] [--follow 0|1] [--comb-look 0|1] "
                 "[--frames ARRAY FROM_S TO_S] "
                 "[per_frame|bayesian_grid|multi_peak|"
                 "robust_regression ...]\n");
    return 2;
  }
  try {
    std::vector<std::string> warnings;
    const sim::Scenario scenario = sim::load_scenario(argv[1], warnings);
    std::vector<doa::TdoaTracker> trackers;
    doa::testing::EvaluationSettings settings;
    int static_null = -1;    // -1: as the scene's config says
    int static_cancel = -1;  // doa.static_null_cancel: -1 as the scene's config says
    bool audibility = false;
    int follow = -1;     // doa.follow_source_tracks: -1 as the scene's config says
    int comb_look = -1;  // doa.comb_look: -1 as the scene's config says
    for (int i = 2; i < argc; ++i) {
      if (argv[i] == std::string("--audible-snr-db") && i + 1 < argc) {
        settings.audible_snr_db = std::stod(argv[++i]);
        continue;
      }
      if (argv[i] == std::string("--audibility")) {
        audibility = true;
        settings.audibility = true;
        continue;
      }
      if (argv[i] == std::string("--breakdown")) {
        audibility = true;
        settings.audibility = true;
        settings.breakdown = true;
        continue;
      }
      if (argv[i] == std::string("--follow") && i + 1 < argc) {
        follow = std::stoi(argv[++i]);
        continue;
      }
      if (argv[i] == std::string("--frames") && i + 3 < argc) {
        settings.frames_array = argv[++i];
        settings.frames_from_s = std::stod(argv[++i]);
        settings.frames_to_s = std::stod(argv[++i]);
        continue;
      }
      if (argv[i] == std::string("--comb-look") && i + 1 < argc) {
        comb_look = std::stoi(argv[++i]);
        continue;
      }
      if (argv[i] == std::string("--static-cancel") && i + 1 < argc) {
        static_cancel = std::stoi(argv[++i]) != 0 ? 1 : 0;
        continue;
      }
      if (argv[i] == std::string("--static-null") && i + 1 < argc) {
        static_null = std::stoi(argv[++i]) != 0 ? 1 : 0;
        continue;
      }
      bool known = false;
      for (const auto kind : {doa::TdoaTracker::per_frame, doa::TdoaTracker::bayesian_grid,
                              doa::TdoaTracker::multi_peak, doa::TdoaTracker::robust_regression}) {
        if (argv[i] == std::string(doa::tdoa_tracker_name(kind))) {
          trackers.push_back(kind);
          known = true;
        }
      }
      if (!known) {
        std::fprintf(stderr, "doa_scene_eval: unknown tracker '%s'\n", argv[i]);
        return 2;
      }
    }
    if (trackers.empty())
      trackers = {doa::TdoaTracker::per_frame, doa::TdoaTracker::bayesian_grid,
                  doa::TdoaTracker::multi_peak, doa::TdoaTracker::robust_regression};
    const doa::testing::RenderedScenario rendered = doa::testing::render_for_evaluation(scenario);
    std::string name = std::filesystem::path(argv[1]).stem().string();
    std::printf(
        "| scene | tracker | array | drone | median deg | p90 deg | coverage | max SNR dB |\n"
        "|---|---|---|---|---|---|---|---|\n");
    for (const doa::TdoaTracker tracker : trackers) {
      doa::DoaParams params = scenario.site.doa;
      params.tdoa_tracker = tracker;
      if (static_null >= 0) params.static_null = static_null == 1;
      if (static_cancel >= 0) params.static_null_cancel = static_cancel == 1;
      if (follow >= 0) params.follow_source_tracks = follow == 1;
      if (comb_look >= 0) params.comb_look = comb_look == 1;
      const doa::testing::SceneResult result = doa::testing::evaluate(rendered, params, settings);
      std::printf("%s",
                  doa::testing::format_rows(name, doa::tdoa_tracker_name(tracker), result).c_str());
      if (audibility) {
        std::printf(
            "\n| scene | array | drone | all frames: n, found | background >= 0 dB | >= 6 dB | "
            "band vs all >= 0 dB | >= 6 dB | comb vs all >= 0 dB | >= 6 dB | median el error "
            "deg |\n|---|---|---|---|---|---|---|---|---|---|---|\n%s\n",
            doa::testing::format_audibility_rows(name, result, settings.found_within_deg).c_str());
      }
      if (settings.breakdown)
        std::printf(
            "%s\n",
            doa::testing::format_breakdown_rows(name, result, settings.found_within_deg).c_str());
      std::fflush(stdout);
    }
  } catch (const std::exception& error) {
    std::fprintf(stderr, "doa_scene_eval: %s\n", error.what());
    return 1;
  }
  return 0;
}
