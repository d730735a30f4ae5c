// The comb look (doa.comb_look, docs/doa.md stage 7): after the free search stops under the SRP
// floor, one look on the kept bins of the comb their power shows, against the floor for that
// many bins.
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "doa/array_geometry.hpp"
#include "doa/node_pipeline.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa::comb_look_test {
namespace {

constexpr double kRate = 48000.0;
constexpr double kSeconds = 3.0;
constexpr double kLoudRms = 0.05;
const double kCombRms = kLoudRms * std::pow(10.0, -11.0 / 20.0);
// Frames counted from here: the sources on for a whole frame.
constexpr double kCountFromS = 0.7;

// The sources start after the node's noise floor has learnt the sensor noise alone.
constexpr double kStartS = 0.5;

void add_source_from_start(testing::Recording& recording, const ArrayGeometry& geometry,
                           const Eigen::Vector3d& direction, const testing::BandNoise& source,
                           double rms) {
  const std::vector<double> delays = testing::plane_wave_delays(geometry, direction, 343.0);
  for (int mic = 0; mic < recording.channels; ++mic) {
    std::vector<double> samples = source.delayed(delays[static_cast<std::size_t>(mic)], rms);
    std::fill_n(samples.begin(), static_cast<std::ptrdiff_t>(kStartS * kRate), 0.0);
    recording.add(mic, samples);
  }
}

// A loud broadband source over the lower two thirds of the band (its bins are dropped once it is
// found) and incoherent sensor noise over the whole band.
testing::Recording loud_source_and_noise(const ArrayGeometry& geometry,
                                         const Eigen::Vector3d& loud) {
  const auto frames = static_cast<std::size_t>(kSeconds * kRate);
  testing::Recording recording = testing::silent_recording(4, frames);
  const testing::BandNoise broadband(static_cast<int>(frames), kRate, 800.0, 2400.0, 31);
  add_source_from_start(recording, geometry, loud, broadband, kLoudRms);
  testing::add_sensor_noise(recording, kRate, 200.0, 8000.0, 0.02, 32);
  return recording;
}

// Per mic, a rotor-like comb whose phases wander independently at each mic (a random walk
// decorrelating over ~0.02 s): lines in every mic's power, no direction in their phases.
void add_incoherent_comb(testing::Recording& recording, double fundamental_hz, double rms) {
  std::mt19937 random(41);
  std::normal_distribution<double> step(0.0, 0.02);
  const std::size_t frames = recording.frames();
  for (int mic = 0; mic < recording.channels; ++mic) {
    std::vector<double> samples(frames, 0.0);
    for (int h = 4; h * fundamental_hz <= 3500.0; ++h) {
      double phase = 0.0;
      const double omega = 2.0 * std::numbers::pi * h * fundamental_hz / kRate;
      for (std::size_t n = 0; n < frames; ++n) {
        phase += step(random);
        samples[n] += std::cos(omega * static_cast<double>(n) + phase);
      }
    }
    double sum = 0.0;
    for (const double value : samples) sum += value * value;
    const double scale = rms / std::sqrt(sum / static_cast<double>(frames));
    for (double& value : samples) value *= scale;
    recording.add(mic, samples);
  }
}

struct Finds {
  int frames = 0;
  int comb_frames = 0;  // frames with a DOA within 1 deg of the comb
  int loud_frames = 0;  // ... of the loud source
  int stray_doas = 0;   // DOAs more than 1 deg from both
  std::int64_t comb_looks = 0;
  std::int64_t comb_look_sources = 0;
};

Finds run(const ArrayGeometry& geometry, const testing::Recording& recording,
          const Eigen::Vector3d& loud, const Eigen::Vector3d& comb, bool comb_look) {
  DoaParams params;
  params.tdoa_tracker = TdoaTracker::per_frame;
  params.comb_look = comb_look;
  params.ground_echo = false;          // plane waves: no ground to remove an image by
  params.static_look.enabled = false;  // the frame's own looks alone
  NodePipeline pipeline(geometry, 0, params, kRate, 343.0);
  std::vector<DoaMeasurement> doas;
  for (std::size_t first = 0; first < recording.frames(); first += 4800)
    pipeline.process(recording.view(first, std::min<std::size_t>(4800, recording.frames() - first)),
                     doas);
  Finds finds;
  const auto first_frame = static_cast<int>(std::lround(kCountFromS / 0.05));
  finds.frames = static_cast<int>(pipeline.diagnostics().frames_processed) - first_frame;
  std::vector<int> comb_seen(static_cast<std::size_t>(finds.frames) + first_frame + 1, 0);
  std::vector<int> loud_seen(comb_seen.size(), 0);
  for (const DoaMeasurement& doa : doas) {
    if (doa.time_s < kCountFromS) continue;
    const auto frame =
        std::min(comb_seen.size() - 1, static_cast<std::size_t>(std::lround(doa.time_s / 0.05)));
    const bool at_comb = angle_between_deg(doa.direction, comb) <= 1.0;
    const bool at_loud = angle_between_deg(doa.direction, loud) <= 1.0;
    comb_seen[frame] |= at_comb ? 1 : 0;
    loud_seen[frame] |= at_loud ? 1 : 0;
    finds.stray_doas += !at_comb && !at_loud ? 1 : 0;
  }
  for (std::size_t f = 0; f < comb_seen.size(); ++f) {
    finds.comb_frames += comb_seen[f];
    finds.loud_frames += loud_seen[f];
  }
  finds.comb_looks = pipeline.diagnostics().comb_looks;
  finds.comb_look_sources = pipeline.diagnostics().comb_look_sources;
  return finds;
}

void print(const char* what, const Finds& finds) {
  std::printf(
      "%s: %d frames, comb within 1 deg in %d, loud in %d, %d stray DOAs, %lld comb looks, "
      "%lld sources added\n",
      what, finds.frames, finds.comb_frames, finds.loud_frames, finds.stray_doas,
      static_cast<long long>(finds.comb_looks), static_cast<long long>(finds.comb_look_sources));
}

// A rotor's comb (205 Hz, lines only) 11 dB under a loud broadband source, about as loud as the
// sensor noise in the bins the loud source leaves (2.4-3.5 kHz): once the loud source's bins are
// dropped, the comb's lines are a small share of what is left and the look over every kept bin
// stays under the floor; on its lines alone it clears its floor, in its own direction.
TEST(CombLook, FindsAWeakCombTheWholeBandLookLeavesUnderTheFloor) {
  const ArrayGeometry geometry = testing::tetrahedron(0.0);
  const Eigen::Vector3d loud = direction_from_azel_deg(-60.0, 15.0);
  const Eigen::Vector3d comb = direction_from_azel_deg(70.0, 25.0);
  testing::Recording recording = loud_source_and_noise(geometry, loud);
  const auto frames = static_cast<int>(recording.frames());
  const testing::BandNoise lines =
      testing::BandNoise::comb(frames, kRate, 205.0, 800.0, 3500.0, 33);
  add_source_from_start(recording, geometry, comb, lines, kCombRms);
  const Finds off = run(geometry, recording, loud, comb, false);
  const Finds on = run(geometry, recording, loud, comb, true);
  print("comb look off", off);
  print("comb look on", on);
  EXPECT_LE(off.comb_frames, off.frames / 5);  // the scene shows the floor's miss
  EXPECT_GE(on.comb_frames, on.frames * 9 / 10);
  EXPECT_GE(on.loud_frames, on.frames * 9 / 10);
  EXPECT_LE(on.stray_doas, on.frames / 20);
}

// Lines in every mic's power but no direction in their phases (each mic's own hum): the comb
// look is made in most frames and finds nothing over the floor.
TEST(CombLook, FindsNothingInACombWithoutADirection) {
  const ArrayGeometry geometry = testing::tetrahedron(0.0);
  const Eigen::Vector3d loud = direction_from_azel_deg(-60.0, 15.0);
  testing::Recording recording = loud_source_and_noise(geometry, loud);
  add_incoherent_comb(recording, 205.0, kCombRms);
  const Finds on = run(geometry, recording, loud, loud, true);
  print("incoherent comb", on);
  EXPECT_GE(on.comb_looks, on.frames / 2);
  EXPECT_LE(on.comb_look_sources, on.frames / 50);
  EXPECT_LE(on.stray_doas, on.frames / 20);
  EXPECT_GE(on.loud_frames, on.frames * 9 / 10);
}

}  // namespace
}  // namespace dronetrack::doa::comb_look_test
