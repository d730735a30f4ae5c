// A site calibration's corrections at the node (docs/calibration.md): a channel that hears late
// or loud, and a clock that runs ahead, undone before the DOA leaves the node.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "doa/node_pipeline.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa {
namespace {

constexpr double kRate = 48000.0;

struct Outcome {
  double median_error_deg = 0.0;
  double first_time_s = 0.0;
};

// A plane wave whose channels are late by `delay_s` (per mic) and louder by `gain_db`.
Outcome run(const ArrayGeometry& configured, const std::vector<double>& delay_s,
            const std::vector<double>& gain_db) {
  const ArrayGeometry truth = testing::tetrahedron(20.0);
  const Eigen::Vector3d direction = direction_from_azel_deg(70.0, 20.0);
  const auto frames = static_cast<std::size_t>(3.0 * kRate);
  testing::Recording recording = testing::silent_recording(4, frames);
  const testing::BandNoise source(static_cast<int>(frames), kRate, 1000.0, 4000.0, 5);
  const std::vector<double> arrivals = testing::plane_wave_delays(truth, direction, 343.0);
  for (int mic = 0; mic < 4; ++mic) {
    const auto m = static_cast<std::size_t>(mic);
    recording.add(
        mic, source.delayed(arrivals[m] + delay_s[m], 0.05 * std::pow(10.0, gain_db[m] / 20.0)));
  }
  testing::add_sensor_noise(recording, kRate, 200.0, 8000.0, 0.01, 17);
  NodePipeline pipeline(configured, 0, DoaParams{}, kRate, 343.0);
  std::vector<DoaMeasurement> doas;
  for (std::size_t first = 0; first < frames; first += 1024)
    pipeline.process(recording.view(first, std::min<std::size_t>(1024, frames - first)), doas);
  EXPECT_GT(doas.size(), 20u);
  std::vector<double> errors;
  for (const auto& doa : doas) errors.push_back(angle_between_deg(doa.direction, direction));
  std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2),
                   errors.end());
  return {errors[errors.size() / 2], doas.empty() ? 0.0 : doas.front().time_s};
}

TEST(ChannelCorrections, ASkewedChannelIsUndoneAndTheClockOffsetTakenOff) {
  const std::vector<double> skew = {0.0, 1e-4, -0.5e-4, 0.0};  // 0.1 ms: 4.8 samples
  const std::vector<double> gains = {0.0, 1.0, -1.0, 0.5};
  const Outcome plain = run(testing::tetrahedron(20.0), {0, 0, 0, 0}, {0, 0, 0, 0});
  const Outcome skewed = run(testing::tetrahedron(20.0), skew, gains);
  ArrayGeometry corrected = testing::tetrahedron(20.0);
  corrected.channel_delay_s = skew;
  corrected.channel_gain_db = gains;
  corrected.clock_offset_s = 0.004;
  const Outcome undone = run(corrected, skew, gains);
  std::printf("median DOA error: clean %.3f deg, skewed %.3f deg, corrected %.3f deg\n",
              plain.median_error_deg, skewed.median_error_deg, undone.median_error_deg);
  EXPECT_GT(skewed.median_error_deg, 3.0);
  EXPECT_LT(undone.median_error_deg, plain.median_error_deg + 0.1);
  EXPECT_NEAR(undone.first_time_s, plain.first_time_s - 0.004, 1e-9);
}

}  // namespace
}  // namespace dronetrack::doa
