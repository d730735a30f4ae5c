// Issue 4 "done when" on the simulator's bundled scenes, with default DoaParams (the scene's
// own "doa" section): seed-002 accuracy and coverage, the two-drone perimeter, and the ground
// interferer. Slow (renders minutes of 4-channel audio): ctest label "slow".
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "doa/tdoa_tracker.hpp"
#include "sim/scenario.hpp"
#include "tests/doa/scene_eval.hpp"

namespace dronetrack::doa::testing {
namespace {

RenderedScenario load(const std::string& name) {
  std::vector<std::string> warnings;
  return render_for_evaluation(sim::load_scenario(
      std::string(DRONETRACK_SOURCE_DIR) + "/config/scenarios/" + name + ".json", warnings));
}

const DroneAtArray& cell(const SceneResult& result, const std::string& array,
                         const std::string& drone) {
  for (const DroneAtArray& entry : result.cells)
    if (entry.array_id == array && entry.drone_id == drone) return entry;
  throw std::runtime_error("no cell " + array + "/" + drone);
}

TEST(SceneAccuracy, Seed002At10dB) {
  const RenderedScenario scene = load("seed002-rectangle");
  const SceneResult result = evaluate(scene, scene.scenario.site.doa);
  std::printf("%s", format_rows("seed002-rectangle",
                                tdoa_tracker_name(scene.scenario.site.doa.tdoa_tracker), result)
                        .c_str());
  for (const char* array : {"A1", "A2"}) {
    const DroneAtArray& entry = cell(result, array, "D1");
    EXPECT_GT(entry.audible_frames, 500) << array;
    // Issue 4 asks <= 0.2 deg. Measured with the ground echo removed: A1 0.092, A2 0.083 (0.209
    // and 0.135 before; the echo pulled the elevation, docs/doa.md stage 7b).
    EXPECT_LE(entry.median_deg(), 0.15) << array;
    EXPECT_LE(entry.p90_deg(), 0.35) << array;
    EXPECT_GE(entry.coverage(), 0.95) << array;
  }
  EXPECT_LT(result.stray_doas, result.doas / 100);
}

TEST(SceneAccuracy, PerimeterTwoDronesBothFoundWhereBothAreHeard) {
  const RenderedScenario scene = load("perimeter-two-drones");
  EvaluationSettings settings;
  settings.audible_snr_db = 6.0;
  const SceneResult result = evaluate(scene, scene.scenario.site.doa, settings);
  std::printf("%s", format_rows("perimeter-two-drones",
                                tdoa_tracker_name(scene.scenario.site.doa.tdoa_tracker), result)
                        .c_str());
  // Issue 4 asks for both drones at every array that hears both. Each found source's bins are
  // dropped before the next look (SourceBinMask), so the quieter drone shows at all four.
  // Measured (docs/doa.md): coverage 63-96 %, medians 0.17-0.30 deg.
  int arrays_hearing_both = 0;
  for (const char* array : {"N1", "N2", "N3", "N4"}) {
    const DroneAtArray& first = cell(result, array, "D1");
    const DroneAtArray& second = cell(result, array, "D2");
    if (first.audible_frames < 40 || second.audible_frames < 40) continue;
    ++arrays_hearing_both;
    for (const DroneAtArray* drone : {&first, &second}) {
      EXPECT_GE(drone->coverage(), 0.5) << array << " " << drone->drone_id;
      EXPECT_LE(drone->median_deg(), 0.35) << array << " " << drone->drone_id;
    }
  }
  EXPECT_EQ(arrays_hearing_both, 4);
  EXPECT_LT(result.stray_doas, result.doas / 20);
}

// The generator 5 m from A1 is ~12 dB above the drone there: without the static-source null
// A1 finds the drone in 0 of ~800 frames. Issue 4 asks for a median <= 0.5 deg at A1. The
// binary mask alone keeps only the bins the rotor dominates (~8 % of the band at A1): 28-36 %
// coverage across pipeline revisions; with the generator cancelled in its bins instead
// (static_null_cancel, stage 3c) 84.2 % (docs/doa.md): >= 75 % is asserted.
TEST(SceneAccuracy, GroundInterfererNextToA1) {
  const RenderedScenario scene = load("ground-interferer");
  const SceneResult result = evaluate(scene, scene.scenario.site.doa);
  std::printf("%s", format_rows("ground-interferer",
                                tdoa_tracker_name(scene.scenario.site.doa.tdoa_tracker), result)
                        .c_str());
  const DroneAtArray& entry = cell(result, "A1", "D1");
  EXPECT_GT(entry.audible_frames, 100);
  EXPECT_LE(entry.median_deg(), 0.5);
  EXPECT_GE(entry.coverage(), 0.75);
}

}  // namespace
}  // namespace dronetrack::doa::testing
