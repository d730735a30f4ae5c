// NodePipeline end to end on synthetic plane waves: accuracy, frame timing, honest covariance,
// the detection gate, bad input (silence, DC, clipping, NaN/Inf, dropouts, gaps) and two sources.
#include "doa/node_pipeline.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <vector>

#include "common/statistics.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa::node_pipeline_test {
namespace {

constexpr double kRate = 48000.0;
using testing::tetrahedron;

std::vector<DoaMeasurement> run(NodePipeline& pipeline, const testing::Recording& recording,
                                std::size_t block = 1024) {
  std::vector<DoaMeasurement> out;
  for (std::size_t first = 0; first < recording.frames(); first += block)
    pipeline.process(recording.view(first, std::min(block, recording.frames() - first)), out);
  return out;
}

testing::Recording plane_wave(const ArrayGeometry& geometry, const Eigen::Vector3d& direction,
                              double seconds, double source_rms, double noise_rms, unsigned seed) {
  const auto frames = static_cast<std::size_t>(seconds * kRate);
  testing::Recording recording = testing::silent_recording(4, frames);
  const testing::BandNoise source(static_cast<int>(frames), kRate, 1000.0, 4000.0, seed);
  testing::add_source(recording, geometry, direction, source, source_rms);
  if (noise_rms > 0.0)
    testing::add_sensor_noise(recording, kRate, 200.0, 8000.0, noise_rms, seed + 99);
  return recording;
}

TEST(NodePipeline, FindsAPlaneWaveWithFrameCentreTimes) {
  DoaParams params;
  params.tdoa_tracker = TdoaTracker::per_frame;
  const ArrayGeometry geometry = tetrahedron(45.0);
  NodePipeline pipeline(geometry, 3, params, kRate, 343.0);
  EXPECT_EQ(pipeline.frame_length_samples(), 8160);
  EXPECT_EQ(pipeline.hop_samples(), 2400);
  const Eigen::Vector3d truth = direction_from_azel_deg(-160.0, 25.0);
  // Sensor noise is white over 0.2-8 kHz; in the 1.5-3.5 kHz band the SNR is about 10 dB.
  const testing::Recording recording = plane_wave(geometry, truth, 3.0, 0.05, 0.0325, 1);
  const std::vector<DoaMeasurement> doas = run(pipeline, recording, 1000);
  const int frames = static_cast<int>((recording.frames() - 8160) / 2400 + 1);
  EXPECT_EQ(pipeline.diagnostics().frames_processed, frames);
  ASSERT_GE(static_cast<int>(doas.size()), frames - 3);  // the floor needs a frame or two
  std::vector<double> errors;
  for (const DoaMeasurement& doa : doas) {
    errors.push_back(angle_between_deg(doa.direction, truth));
    EXPECT_EQ(doa.array_id, "A1");
    EXPECT_EQ(doa.array_index, 3);
    EXPECT_EQ(doa.ambiguity, DoaAmbiguity::none);
    EXPECT_NEAR(doa.direction.norm(), 1.0, 1e-9);
    // Centre time of a frame starting at a multiple of the hop.
    const double frame_index = (doa.time_s * kRate - 0.5 * (8160 - 1)) / 2400.0;
    EXPECT_NEAR(frame_index, std::round(frame_index), 1e-9);
    EXPECT_GT(doa.snr_db, 6.0);
  }
  EXPECT_LT(median(errors), 0.3);
  EXPECT_LT(*std::max_element(errors.begin(), errors.end()), 1.5);
  EXPECT_TRUE(pipeline.diagnostics().detecting);
}

// Mean NEES (2 dof) of the pipeline's DOAs of a plane wave in white noise, over four geometries.
double mean_pipeline_nees(const DoaParams& params, int& count) {
  double nees = 0.0;
  count = 0;
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const ArrayGeometry geometry = tetrahedron(10.0 * seed);
    NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
    const Eigen::Vector3d truth = direction_from_azel_deg(37.0 * seed, 5.0 * seed);
    const testing::Recording recording = plane_wave(geometry, truth, 4.0, 0.05, 0.05, seed);
    for (const DoaMeasurement& doa : run(pipeline, recording)) {
      const Eigen::Vector2d error(
          wrap_rad_pi((azimuth_deg(doa.direction) - azimuth_deg(truth)) * std::numbers::pi / 180.0),
          (elevation_deg(doa.direction) - elevation_deg(truth)) * std::numbers::pi / 180.0);
      nees += error.dot(doa.azel_covariance_rad2.inverse() * error);
      ++count;
    }
  }
  return count > 0 ? nees / count : 0.0;
}

TEST(NodePipeline, CovarianceIsHonestWithOverlappingFramesAndTheRegression) {
  // The defaults: 0.17 s frames every 0.05 s, so neighbouring frames share most of their noise,
  // smoothed by the robust regression. A variance that took its 13 frames for independent ones
  // would be 1.6x too small (mean NEES ~3.3).
  DoaParams params;
  params.max_sources = 1;
  int count = 0;
  const double mean_nees = mean_pipeline_nees(params, count);
  std::printf("pipeline NEES, default tracker and hop, over %d DOAs: %.2f (2 expected)\n", count,
              mean_nees);
  ASSERT_GT(count, 200);
  EXPECT_GT(mean_nees, 1.4);
  EXPECT_LT(mean_nees, 2.8);
}

TEST(NodePipeline, CovarianceIsHonest) {
  // NEES over many frames of independent noise: mean near 2 (2 dof), not 20, not 0.2.
  DoaParams params;
  params.tdoa_tracker = TdoaTracker::per_frame;
  params.hop_s = 0.17;  // independent frames
  params.max_sources = 1;
  int count = 0;
  const double mean_nees = mean_pipeline_nees(params, count);
  std::printf("pipeline NEES over %d DOAs: %.2f (2 expected)\n", count, mean_nees);
  ASSERT_GT(count, 50);
  EXPECT_GT(mean_nees, 0.7);
  EXPECT_LT(mean_nees, 5.0);
}

TEST(NodePipeline, NoiseAloneGivesNoDoaAndTheGateOpensForASource) {
  DoaParams params;
  const ArrayGeometry geometry = tetrahedron();
  NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
  testing::Recording noise = testing::silent_recording(4, static_cast<std::size_t>(4 * kRate));
  testing::add_sensor_noise(noise, kRate, 200.0, 8000.0, 0.05, 5);
  EXPECT_TRUE(run(pipeline, noise).empty());
  EXPECT_FALSE(pipeline.diagnostics().detecting);
  EXPECT_LT(pipeline.diagnostics().snr_db, params.detection_snr_db);
  EXPECT_GT(pipeline.diagnostics().noise_floor_dbfs, -60.0);

  // The same noise with a source 10 dB above it: detected from the next frames on.
  NodePipeline fresh(geometry, 0, params, kRate, 343.0);
  const Eigen::Vector3d truth = direction_from_azel_deg(100.0, 10.0);
  testing::Recording loud = plane_wave(geometry, truth, 4.0, 0.05, 0.0, 6);
  testing::add_sensor_noise(loud, kRate, 200.0, 8000.0, 0.0325, 5);
  const std::vector<DoaMeasurement> doas = run(fresh, loud);
  EXPECT_GT(doas.size(), 60U);
  EXPECT_TRUE(fresh.diagnostics().detecting);
  EXPECT_NEAR(fresh.diagnostics().snr_db, 10.0, 3.0);
}

TEST(NodePipeline, OddAudioNeverCrashesNorYieldsADoa) {
  DoaParams params;
  const ArrayGeometry geometry = tetrahedron();
  const auto frames = static_cast<std::size_t>(2 * kRate);
  auto expect_no_doa = [&](const testing::Recording& recording, const char* what) {
    NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
    const std::vector<DoaMeasurement> doas = run(pipeline, recording, 333);
    EXPECT_TRUE(doas.empty()) << what;
    EXPECT_GT(pipeline.diagnostics().frames_processed, 20) << what;
    return pipeline.diagnostics();
  };
  expect_no_doa(testing::silent_recording(4, frames), "silence");
  testing::Recording dc = testing::silent_recording(4, frames);
  std::fill(dc.interleaved.begin(), dc.interleaved.end(), 0.5F);
  expect_no_doa(dc, "DC");
  // A loud source clipped hard at full scale.
  const Eigen::Vector3d truth = direction_from_azel_deg(30.0, 30.0);
  testing::Recording clipped = plane_wave(geometry, truth, 2.0, 3.0, 0.0, 9);
  for (float& sample : clipped.interleaved) sample = std::clamp(sample, -1.0F, 1.0F);
  EXPECT_GT(expect_no_doa(clipped, "clipping").clipped_samples, 1000);
  // A clean source with NaN and Inf sprinkled every 1000 samples.
  testing::Recording corrupted = plane_wave(geometry, truth, 2.0, 0.05, 0.01, 9);
  for (std::size_t n = 0; n < corrupted.interleaved.size(); n += 1000)
    corrupted.interleaved[n] = (n / 1000) % 2 == 0 ? std::numeric_limits<float>::quiet_NaN()
                                                   : std::numeric_limits<float>::infinity();
  EXPECT_GT(expect_no_doa(corrupted, "NaN/Inf").non_finite_samples, 300);
  // Dropouts: the source drops to exact zeros; frames entirely inside the dropout give nothing.
  testing::Recording dropout = testing::silent_recording(4, frames);
  expect_no_doa(dropout, "dropout");

  // Blocks with gaps, a rewind, the wrong channel count, null data and zero length.
  NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
  const testing::Recording good = plane_wave(geometry, truth, 2.0, 0.05, 0.01, 3);
  std::vector<DoaMeasurement> out;
  pipeline.process(good.view(0, 20000), out);
  pipeline.process(good.view(30000, 20000), out);  // gap: reframe
  pipeline.process(good.view(10000, 5000), out);   // rewind: reframe
  AudioBlockView wrong = good.view(15000, 100);
  wrong.channels = 3;
  pipeline.process(wrong, out);
  pipeline.process(AudioBlockView{15000, 4, 100, nullptr}, out);
  pipeline.process(AudioBlockView{15000, 4, 0, nullptr}, out);
  EXPECT_EQ(pipeline.diagnostics().stream_gaps, 2);
  EXPECT_EQ(pipeline.diagnostics().rejected_blocks, 2);
  for (const DoaMeasurement& doa : out) EXPECT_LT(angle_between_deg(doa.direction, truth), 2.0);
}

TEST(NodePipeline, DropoutInsideASourceGivesNoDoaForSilentFrames) {
  DoaParams params;
  params.frame_s = 0.2;
  params.hop_s = 0.2;
  const ArrayGeometry geometry = tetrahedron();
  const Eigen::Vector3d truth = direction_from_azel_deg(-45.0, 15.0);
  testing::Recording recording = plane_wave(geometry, truth, 4.0, 0.05, 0.01, 4);
  // Frames 10..12 (0.2 s each) are a dropout: every channel exactly zero.
  std::fill(recording.interleaved.begin() + 10 * 9600 * 4,
            recording.interleaved.begin() + 13 * 9600 * 4, 0.0F);
  NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
  const std::vector<DoaMeasurement> doas = run(pipeline, recording);
  for (const DoaMeasurement& doa : doas) {
    const int frame = static_cast<int>(doa.time_s / 0.2);
    EXPECT_TRUE(frame < 10 || frame > 12) << doa.time_s;
    EXPECT_LT(angle_between_deg(doa.direction, truth), 1.0);
  }
  // 20 frames, 3 silent, and the default robust_regression reports each frame 6 frames later,
  // so the last 6 are still in its window when the recording ends.
  EXPECT_GE(doas.size(), static_cast<std::size_t>(20 - 3 - params.regression_delay_frames));
}

TEST(NodePipeline, SeedFrameAndHopWork) {
  DoaParams params;
  params.frame_s = 0.2;
  params.hop_s = 0.2;
  const ArrayGeometry geometry = tetrahedron(-90.0);
  NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
  EXPECT_EQ(pipeline.frame_length_samples(), 9600);
  const Eigen::Vector3d truth = direction_from_azel_deg(179.5, 40.0);
  const std::vector<DoaMeasurement> doas =
      run(pipeline, plane_wave(geometry, truth, 3.0, 0.05, 0.02, 8));
  // 15 frames; robust_regression's last regression_delay_frames are still in its window.
  ASSERT_GE(doas.size(), static_cast<std::size_t>(15 - params.regression_delay_frames));
  for (const DoaMeasurement& doa : doas) EXPECT_LT(angle_between_deg(doa.direction, truth), 0.5);
}

TEST(NodePipeline, SrpPhatFindsTwoSimultaneousSources) {
  DoaParams params;
  params.max_sources = 2;
  params.tdoa_tracker = TdoaTracker::per_frame;
  const ArrayGeometry geometry = tetrahedron(20.0);
  const Eigen::Vector3d first = direction_from_azel_deg(30.0, 20.0);
  const Eigen::Vector3d second = direction_from_azel_deg(-120.0, 45.0);
  testing::Recording recording = plane_wave(geometry, first, 3.0, 0.05, 0.01, 21);
  const testing::BandNoise other(static_cast<int>(recording.frames()), kRate, 1000.0, 4000.0, 77);
  testing::add_source(recording, geometry, second, other, 0.045);
  NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
  const std::vector<DoaMeasurement> doas = run(pipeline, recording);
  int frames_with_both = 0;
  std::vector<double> first_errors;
  std::vector<double> second_errors;
  for (std::size_t i = 0; i < doas.size(); ++i) {
    const double to_first = angle_between_deg(doas[i].direction, first);
    const double to_second = angle_between_deg(doas[i].direction, second);
    EXPECT_LT(std::min(to_first, to_second), 2.0) << "a DOA that is neither source";
    (to_first < to_second ? first_errors : second_errors).push_back(std::min(to_first, to_second));
    if (i + 1 < doas.size() && doas[i + 1].time_s == doas[i].time_s &&
        doas[i + 1].source_index == 1 && doas[i].source_index == 0) {
      const double next_first = angle_between_deg(doas[i + 1].direction, first);
      const double next_second = angle_between_deg(doas[i + 1].direction, second);
      if ((to_first < 2.0 && next_second < 2.0) || (to_second < 2.0 && next_first < 2.0))
        ++frames_with_both;
    }
  }
  const int frames = static_cast<int>(pipeline.diagnostics().frames_processed);
  std::printf("two sources: %d of %d frames give both; median errors %.3f / %.3f deg\n",
              frames_with_both, frames, median(first_errors), median(second_errors));
  EXPECT_GT(frames_with_both, frames * 3 / 4);
  EXPECT_LT(median(first_errors), 0.5);
  EXPECT_LT(median(second_errors), 0.5);
}

TEST(NodePipeline, EachBandFindsItsOwnSourceOnA3DArray) {
  // Per-band detection (issue 15) on a tetrahedron: two sources, each in its own band, every
  // frame gives both, each under its band's index (source_index = band + bands x rank), and no
  // band reports the other's source.
  DoaParams params;
  params.bands_hz = {{1000.0, 3500.0}, {4500.0, 7000.0}};
  const ArrayGeometry geometry = tetrahedron(20.0);
  const std::array<Eigen::Vector3d, 2> truths{direction_from_azel_deg(30.0, 20.0),
                                              direction_from_azel_deg(-120.0, 45.0)};
  const auto frames = static_cast<std::size_t>(3.0 * kRate);
  testing::Recording recording = testing::silent_recording(4, frames);
  for (std::size_t b = 0; b < 2; ++b) {
    const FrequencyBand& band = params.bands_hz[b];
    const testing::BandNoise source(static_cast<int>(frames), kRate, band.low_hz, band.high_hz,
                                    41 + static_cast<unsigned>(b));
    testing::add_source(recording, geometry, truths[b], source, 0.05);
  }
  testing::add_sensor_noise(recording, kRate, 200.0, 12000.0, 0.02, 43);
  NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
  const std::vector<DoaMeasurement> doas = run(pipeline, recording);
  std::array<std::vector<double>, 2> errors;
  int frames_with_both = 0;
  for (std::size_t i = 0; i < doas.size(); ++i) {
    ASSERT_GE(doas[i].source_index, 0);
    ASSERT_LT(doas[i].source_index, 2) << "a second source in a band that holds one";
    const auto band = static_cast<std::size_t>(doas[i].source_index);
    errors[band].push_back(angle_between_deg(doas[i].direction, truths[band]));
    EXPECT_LT(errors[band].back(), 1.0) << "band " << band << " at " << doas[i].time_s;
    if (i > 0 && doas[i - 1].time_s == doas[i].time_s && doas[i - 1].source_index == 0 &&
        doas[i].source_index == 1)
      ++frames_with_both;
  }
  std::printf("two bands on a tetrahedron: %d frames give both; median errors %.3f / %.3f deg\n",
              frames_with_both, median(errors[0]), median(errors[1]));
  EXPECT_GE(frames_with_both, 45);
  EXPECT_EQ(errors[0].size(), errors[1].size());
  EXPECT_LT(median(errors[0]), 0.5);
  EXPECT_LT(median(errors[1]), 0.5);
}

TEST(NodePipeline, RejectsBadParametersByName) {
  DoaParams params;
  params.hop_s = 0.5;
  EXPECT_THROW(NodePipeline(tetrahedron(), 0, params, kRate, 343.0), std::invalid_argument);
  params = DoaParams{};
  params.bands_hz = {{30000.0, 40000.0}};
  EXPECT_THROW(NodePipeline(tetrahedron(), 0, params, kRate, 343.0), std::invalid_argument);
  ArrayGeometry one = tetrahedron();
  one.mics_m.resize(1);
  EXPECT_THROW(NodePipeline(one, 0, DoaParams{}, kRate, 343.0), std::invalid_argument);
}

}  // namespace
}  // namespace dronetrack::doa::node_pipeline_test
