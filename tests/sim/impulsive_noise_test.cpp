// Alpha-stable bursts in the audio (sim/impulsive_noise.hpp): where they fall, how loud, and that a
// scenario's noise.impulsive key renders them.
#include "sim/impulsive_noise.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <gtest/gtest.h>

#include "sim_test_util.hpp"

namespace dronetrack::sim::impulsive_noise_test {
namespace {

constexpr double kRate = 48000.0;
constexpr std::size_t kChannels = 4;

// Which channels carry a burst in each slot (any non-zero sample).
std::vector<std::vector<bool>> bursts_of(const std::vector<float>& samples,
                                         std::size_t slot_frames) {
  const std::size_t frames = samples.size() / kChannels;
  std::vector<std::vector<bool>> out(frames / slot_frames, std::vector<bool>(kChannels, false));
  for (std::size_t n = 0; n < out.size() * slot_frames; ++n)
    for (std::size_t c = 0; c < kChannels; ++c)
      if (samples[n * kChannels + c] != 0.0f) out[n / slot_frames][c] = true;
  return out;
}

TEST(ImpulsiveNoise, BurstsFillTheirShareOfSlotsOnEveryMicAtOnce) {
  ImpulsiveNoise spec;
  spec.enabled = true;
  spec.share = 0.2;
  spec.burst_s = 0.01;                                                                 // 480 frames
  std::vector<float> samples(static_cast<std::size_t>(kRate) * 20 * kChannels, 0.0f);  // 2000 slots
  const ImpulsiveCounts counts = add_impulsive_noise(spec, 1e-3, kRate, 7, 0, kChannels,
                                                     samples.size() / kChannels, samples.data());
  EXPECT_EQ(counts.slots, 2000u);
  // Binomial(2000, 0.2): 400 +- 18.
  EXPECT_NEAR(static_cast<double>(counts.bursts), 400.0, 4.0 * 18.0);
  // Alpha 1.5's tail: P(|x| > 1000 c) is a few 1e-5, so a handful of the 768 000 burst samples
  // reach full scale, and stop there.
  EXPECT_GT(counts.clipped_samples, 0u);
  EXPECT_LT(counts.clipped_samples, 100u);
  EXPECT_LE(*std::max_element(samples.begin(), samples.end()), 1.0f);
  EXPECT_GE(*std::min_element(samples.begin(), samples.end()), -1.0f);
  std::size_t seen = 0;
  for (const auto& slot : bursts_of(samples, 480)) {
    const auto on = static_cast<std::size_t>(std::count(slot.begin(), slot.end(), true));
    EXPECT_TRUE(on == 0 || on == kChannels);  // one event, every mic
    seen += on == kChannels;
  }
  EXPECT_EQ(seen, counts.bursts);
}

TEST(ImpulsiveNoise, PerChannelBurstsAreIndependent) {
  ImpulsiveNoise spec;
  spec.enabled = true;
  spec.share = 0.5;
  spec.burst_s = 0.01;
  spec.per_channel = true;
  std::vector<float> samples(static_cast<std::size_t>(kRate) * 10 * kChannels, 0.0f);  // 1000 slots
  const ImpulsiveCounts counts = add_impulsive_noise(spec, 1e-3, kRate, 7, 0, kChannels,
                                                     samples.size() / kChannels, samples.data());
  EXPECT_NEAR(static_cast<double>(counts.bursts), 0.5 * 4000.0, 4.0 * std::sqrt(1000.0));
  // Independent: all four on in 1/16 of the slots, not 1/2.
  std::size_t all_on = 0;
  for (const auto& slot : bursts_of(samples, 480))
    all_on += std::count(slot.begin(), slot.end(), true) == 4;
  EXPECT_NEAR(static_cast<double>(all_on), 1000.0 / 16.0, 4.0 * std::sqrt(1000.0 / 16.0));
}

TEST(ImpulsiveNoise, GaussianAtAlphaTwoHeavyTailedBelow) {
  ImpulsiveNoise spec;
  spec.enabled = true;
  spec.share = 1.0;
  const double rms = 0.01;
  const std::size_t frames = 200000;
  auto render = [&](double alpha) {
    spec.alpha = alpha;
    std::vector<float> samples(frames * kChannels, 0.0f);
    add_impulsive_noise(spec, rms, kRate, 3, 1, kChannels, frames, samples.data());
    std::vector<double> magnitudes;
    for (float x : samples) magnitudes.push_back(std::abs(x));
    std::sort(magnitudes.begin(), magnitudes.end());
    return magnitudes;
  };
  const auto gaussian = render(2.0);
  double power = 0.0;
  for (double x : gaussian) power += x * x;
  EXPECT_NEAR(std::sqrt(power / static_cast<double>(gaussian.size())), rms, 0.01 * rms);
  // 99.99 % point of |N(0, r)|: 3.89 r. Alpha 1.5's is far beyond (its tail falls as x^-1.5).
  const auto quantile = [](const std::vector<double>& x) { return x[x.size() * 9999 / 10000]; };
  EXPECT_NEAR(quantile(gaussian), 3.89 * rms, 0.15 * rms);
  EXPECT_GT(quantile(render(1.5)), 20.0 * rms);
}

TEST(ImpulsiveNoise, ScenarioKeyRendersBursts) {
  nlohmann::json document =
      test::scene({{"id", "D1"},
                   {"level_db", 85},
                   {"signal", {{"type", "rotor"}, {"blade_pass_hz", 170}}},
                   {"trajectory", {{"type", "hover"}, {"position_m", {30, 40, 20}}}}},
                  1.0);
  const RenderedArray clean = render_array(parse_scenario(document, "."), 0);
  document["noise"] = {{"impulsive", {{"snr_db", 0}, {"share", 0.3}, {"per_channel", true}}}};
  const Scenario noisy = parse_scenario(document, ".");
  EXPECT_TRUE(noisy.noise.impulsive.enabled);
  EXPECT_EQ(noisy.noise.impulsive.share, 0.3);
  EXPECT_TRUE(noisy.noise.impulsive.per_channel);
  const RenderedArray bursty = render_array(noisy, 0);
  ASSERT_EQ(clean.samples.size(), bursty.samples.size());
  std::size_t changed = 0;
  for (std::size_t i = 0; i < clean.samples.size(); ++i)
    changed += clean.samples[i] != bursty.samples[i];
  // 30 % of the 50 slots of each of 4 channels: 60 +- 6.5 slots.
  EXPECT_NEAR(static_cast<double>(changed) / static_cast<double>(clean.samples.size()), 0.3, 0.12);
  document["noise"]["impulsive"]["level_db"] = 80;  // both: one of them only
  EXPECT_THROW(parse_scenario(document, "."), config::ConfigError);
}

}  // namespace
}  // namespace dronetrack::sim::impulsive_noise_test
