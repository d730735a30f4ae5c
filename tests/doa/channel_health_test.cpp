// ChannelHealth on synthetic blocks with known answers: exact non-finite and clipped counts,
// the clipping share, DC offset, silence and absurd levels per channel, each problem raised
// once per channel (not per block), raised again only after it cleared and rewarn_s passed.
#include "doa/channel_health.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "doa/node_pipeline.hpp"
#include "doa/spectral_frame.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa::channel_health_test {
namespace {

constexpr double kRate = 8000.0;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// `channels` channels of `seconds`, channel c a sine of amplitude `amplitude` at 300 (c + 1) Hz.
testing::Recording sines(int channels, double seconds, double amplitude = 0.3) {
  testing::Recording recording =
      testing::silent_recording(channels, static_cast<std::size_t>(seconds * kRate));
  for (std::size_t n = 0; n < recording.frames(); ++n)
    for (int c = 0; c < channels; ++c)
      recording.interleaved[n * static_cast<std::size_t>(channels) + static_cast<std::size_t>(c)] =
          static_cast<float>(amplitude * std::sin(2.0 * std::numbers::pi * 300.0 * (c + 1) *
                                                  static_cast<double>(n) / kRate));
  return recording;
}

float& at(testing::Recording& recording, std::size_t frame, int channel) {
  return recording.interleaved[frame * static_cast<std::size_t>(recording.channels) +
                               static_cast<std::size_t>(channel)];
}

// Feeds the recording in blocks through a framer with the health as its observer, as the node
// does (frame and hop boundaries anywhere in the stretches); returns every event raised,
// finish() included.
std::vector<HealthEvent> feed(ChannelHealth& health, const testing::Recording& recording,
                              std::size_t block = 400, bool finish = true) {
  std::vector<HealthEvent> events;
  Framer framer(recording.channels, 1000, 300);
  for (std::size_t first = 0; first < recording.frames(); first += block) {
    health.clear_events();
    framer.push(
        recording.view(first, std::min(block, recording.frames() - first)), [](const FrameView&) {},
        health);
    events.insert(events.end(), health.events().begin(), health.events().end());
  }
  if (finish) {
    health.finish();
    events.insert(events.end(), health.events().begin(), health.events().end());
  }
  return events;
}

int count(const std::vector<HealthEvent>& events, int channel, HealthProblem problem) {
  int n = 0;
  for (const HealthEvent& event : events) n += event.channel == channel && event.problem == problem;
  return n;
}

const HealthEvent* find(const std::vector<HealthEvent>& events, int channel,
                        HealthProblem problem) {
  for (const HealthEvent& event : events)
    if (event.channel == channel && event.problem == problem) return &event;
  return nullptr;
}

TEST(ChannelHealth, CleanAudioRaisesNothing) {
  ChannelHealth health(4, kRate);
  const std::vector<HealthEvent> events = feed(health, sines(4, 5.0));
  EXPECT_TRUE(events.empty());
  for (int c = 0; c < 4; ++c) {
    EXPECT_EQ(health.channel(c).samples, static_cast<std::int64_t>(5.0 * kRate));
    EXPECT_EQ(health.channel(c).problems_seen, 0) << c;
    EXPECT_NEAR(health.channel(c).rms_dbfs, 20.0 * std::log10(0.3 / std::sqrt(2.0)), 0.01);
  }
}

TEST(ChannelHealth, CountsNonFiniteSamplesPerChannelAndRaisesOnce) {
  ChannelHealth health(3, kRate);
  testing::Recording recording = sines(3, 4.0);
  // Channel 1: 37 NaN and 3 +-Inf, the first at sample 1234 (0.15425 s); channel 2: one NaN at
  // 2.5 s; channel 0 clean.
  for (int k = 0; k < 37; ++k) at(recording, 1234 + 100 * static_cast<std::size_t>(k), 1) = kNaN;
  at(recording, 7000, 1) = kInf;
  at(recording, 7001, 1) = -kInf;
  at(recording, 7003, 1) = kInf;
  at(recording, 20000, 2) = kNaN;
  const std::vector<HealthEvent> events = feed(health, recording, 333);
  EXPECT_EQ(health.channel(0).non_finite_samples, 0);
  EXPECT_EQ(health.channel(1).non_finite_samples, 40);
  EXPECT_EQ(health.channel(2).non_finite_samples, 1);
  EXPECT_EQ(health.non_finite_samples(), 41);
  ASSERT_EQ(events.size(), 2U);
  const HealthEvent* one = find(events, 1, HealthProblem::non_finite);
  ASSERT_NE(one, nullptr);
  EXPECT_NEAR(one->since_s, 1234 / kRate, 1e-12);
  EXPECT_NEAR(one->share, 40 / kRate, 1e-12);
  EXPECT_DOUBLE_EQ(one->time_s, 1.0) << "raised at the end of the first stretch";
  const HealthEvent* two = find(events, 2, HealthProblem::non_finite);
  ASSERT_NE(two, nullptr);
  EXPECT_NEAR(two->since_s, 2.5, 1e-12);
  EXPECT_TRUE(has_problem(health.channel(1).problems_seen, HealthProblem::non_finite));
  EXPECT_EQ(health.channel(1).problems, 0) << "cleared on the last stretch";
  EXPECT_EQ(health.channel(0).problems_seen, 0);
}

TEST(ChannelHealth, AnAllNaNChannelIsNonFiniteOnlyOnceOverManyBlocks) {
  ChannelHealth health(4, kRate);
  testing::Recording recording = sines(4, 30.0);
  for (std::size_t n = 0; n < recording.frames(); ++n) at(recording, n, 3) = kNaN;
  // 0.05 s blocks: 600 blocks, 30 stretches, one warning.
  const std::vector<HealthEvent> events = feed(health, recording, 400);
  ASSERT_EQ(events.size(), 1U);
  EXPECT_EQ(events[0].channel, 3);
  EXPECT_EQ(events[0].problem, HealthProblem::non_finite);
  EXPECT_EQ(events[0].share, 1.0);
  EXPECT_EQ(events[0].since_s, 0.0);
  EXPECT_EQ(health.channel(3).non_finite_samples, static_cast<std::int64_t>(recording.frames()));
  EXPECT_EQ(health.channel(3).problems, health_flag(HealthProblem::non_finite))
      << "no level to call silent: non-finite only";
}

TEST(ChannelHealth, ClippingShareIsCountedAndRaisedAboveItsThreshold) {
  ChannelHealth health(3, kRate);  // clipped_share 0.01
  testing::Recording recording = sines(3, 2.0, 0.5);
  // Channel 0: 5 % of its samples at full scale (every 20th, +-1.0); channel 1: 0.5 % (every
  // 200th at 0.9995), below the share; channel 2: one sample at 0.998, under the clip level.
  std::int64_t clipped_0 = 0;
  std::int64_t clipped_1 = 0;
  for (std::size_t n = 0; n < recording.frames(); ++n) {
    if (n % 20 == 7) {
      at(recording, n, 0) = n % 40 == 7 ? 1.0F : -1.0F;
      ++clipped_0;
    }
    if (n % 200 == 3) {
      at(recording, n, 1) = 0.9995F;
      ++clipped_1;
    }
  }
  at(recording, 100, 2) = 0.998F;
  const std::vector<HealthEvent> events = feed(health, recording, 1000);
  EXPECT_EQ(health.channel(0).clipped_samples, clipped_0);
  EXPECT_EQ(health.channel(1).clipped_samples, clipped_1);
  EXPECT_EQ(health.channel(2).clipped_samples, 0);
  EXPECT_EQ(health.clipped_samples(), clipped_0 + clipped_1);
  ASSERT_EQ(events.size(), 1U);
  EXPECT_EQ(events[0].channel, 0);
  EXPECT_EQ(events[0].problem, HealthProblem::clipped);
  EXPECT_DOUBLE_EQ(events[0].share, 0.05);
  EXPECT_NEAR(events[0].since_s, 7 / kRate, 1e-12);
  EXPECT_EQ(health.channel(1).problems_seen, 0);
}

TEST(ChannelHealth, DcOffsetRelativeToTheRmsOrAboveMinus20Dbfs) {
  ChannelHealth health(4, kRate);
  testing::Recording recording = sines(4, 2.0, 0.01);
  for (std::size_t n = 0; n < recording.frames(); ++n) {
    at(recording, n, 0) += 0.05F;   // mean 0.05 against RMS ~0.0505: > 0.9 x RMS
    at(recording, n, 1) += 0.002F;  // mean 0.002 against RMS ~0.0075: fine
    at(recording, n, 2) = 0.5F * at(recording, n, 2) / 0.01F + 0.15F;  // 0.15 > 0.1, RMS 0.39
  }
  const std::vector<HealthEvent> events = feed(health, recording);
  EXPECT_EQ(count(events, 0, HealthProblem::dc_offset), 1);
  EXPECT_EQ(count(events, 1, HealthProblem::dc_offset), 0);
  EXPECT_EQ(count(events, 2, HealthProblem::dc_offset), 1);
  EXPECT_EQ(count(events, 3, HealthProblem::dc_offset), 0);
  EXPECT_EQ(events.size(), 2U);
  const HealthEvent* dc = find(events, 0, HealthProblem::dc_offset);
  ASSERT_NE(dc, nullptr);
  EXPECT_NEAR(dc->mean, 0.05, 1e-4);
  EXPECT_EQ(dc->since_s, 0.0);
  EXPECT_NEAR(health.channel(2).mean, 0.15, 1e-4);
}

TEST(ChannelHealth, PureDcIsADcOffset) {
  ChannelHealth health(2, kRate);
  testing::Recording recording = testing::silent_recording(2, static_cast<std::size_t>(3 * kRate));
  for (std::size_t n = 0; n < recording.frames(); ++n) at(recording, n, 1) = -0.25F;
  const std::vector<HealthEvent> events = feed(health, recording);
  EXPECT_EQ(count(events, 1, HealthProblem::dc_offset), 1);
  EXPECT_EQ(count(events, 1, HealthProblem::silent), 0);
  EXPECT_EQ(count(events, 0, HealthProblem::silent), 1) << "channel 0 is all zeros";
  EXPECT_EQ(events.size(), 2U);
}

TEST(ChannelHealth, SilenceBelowMinus100DbfsOrExactZeros) {
  ChannelHealth health(3, kRate);
  testing::Recording recording = sines(3, 2.5, 0.0);  // all zeros
  for (std::size_t n = 0; n < recording.frames(); ++n) {
    // Channel 1: a sine at RMS -110 dBFS; channel 2: at RMS -90 dBFS (quiet, not silent).
    const double phase = 2.0 * std::numbers::pi * 440.0 * static_cast<double>(n) / kRate;
    at(recording, n, 1) = static_cast<float>(std::sqrt(2.0) * 3.1623e-6 * std::sin(phase));
    at(recording, n, 2) = static_cast<float>(std::sqrt(2.0) * 3.1623e-5 * std::sin(phase));
  }
  const std::vector<HealthEvent> events = feed(health, recording);
  EXPECT_EQ(count(events, 0, HealthProblem::silent), 1);
  EXPECT_EQ(count(events, 1, HealthProblem::silent), 1);
  EXPECT_EQ(count(events, 2, HealthProblem::silent), 0);
  EXPECT_EQ(events.size(), 2U);
  const HealthEvent* zeros = find(events, 0, HealthProblem::silent);
  ASSERT_NE(zeros, nullptr);
  EXPECT_EQ(zeros->peak, 0.0);
  EXPECT_EQ(zeros->since_s, 0.0);
  EXPECT_NEAR(find(events, 1, HealthProblem::silent)->rms_dbfs, -110.0, 0.1);
  EXPECT_NEAR(health.channel(2).rms_dbfs, -90.0, 0.1);
}

TEST(ChannelHealth, AbsurdLevelSaysItAloneAndCountsItsSamples) {
  ChannelHealth health(2, kRate);
  testing::Recording recording = sines(2, 2.0, 0.3);
  std::int64_t absurd = 0;
  for (std::size_t n = 0; n < recording.frames(); ++n) {
    float& sample = at(recording, n, 1);
    sample *= 1e30F;  // a float file written without scaling
    absurd += std::fabs(sample) > 4.0F;
  }
  const std::vector<HealthEvent> events = feed(health, recording);
  ASSERT_EQ(events.size(), 1U) << "not also clipping, DC or silence";
  EXPECT_EQ(events[0].channel, 1);
  EXPECT_EQ(events[0].problem, HealthProblem::absurd_level);
  EXPECT_GT(events[0].peak, 0.29e30);
  EXPECT_LE(events[0].peak, 0.30001e30);
  EXPECT_EQ(health.channel(1).absurd_samples, absurd);
  EXPECT_EQ(health.channel(1).clipped_samples, absurd) << "beyond full scale counts as clipped";
  EXPECT_EQ(health.channel(0).problems_seen, 0);
}

TEST(ChannelHealth, AProblemThatReturnsIsRaisedAgainOnlyAfterRewarnS) {
  ChannelHealthSettings settings;
  settings.rewarn_s = 10.0;
  ChannelHealth health(1, kRate, settings);
  testing::Recording recording = sines(1, 25.0);
  // NaN bursts in 0-2 s, 4-6 s (back within 10 s of the first warning) and 8-25 s.
  for (std::size_t n = 0; n < recording.frames(); ++n) {
    const double t = static_cast<double>(n) / kRate;
    if ((t >= 0.5 && t < 2.0) || (t >= 4.0 && t < 6.0) || t >= 8.0) at(recording, n, 0) = kNaN;
  }
  const std::vector<HealthEvent> events = feed(health, recording, 400);
  ASSERT_EQ(events.size(), 2U);
  EXPECT_EQ(events[0].time_s, 1.0);
  EXPECT_EQ(events[0].since_s, 0.5);
  // The episode from 8 s was due at 9 s but 9 - 1 < 10: raised at the first stretch end 10 s
  // after the first warning, still saying since when it lasts.
  EXPECT_EQ(events[1].time_s, 11.0);
  EXPECT_EQ(events[1].since_s, 8.0);
}

TEST(ChannelHealth, FinishJudgesALastStretchOfAtLeastAQuarterSecond) {
  testing::Recording recording = sines(2, 0.5);
  for (std::size_t n = 0; n < recording.frames(); ++n) at(recording, n, 0) = kNaN;
  ChannelHealth health(2, kRate);
  EXPECT_TRUE(feed(health, recording, 400, false).empty()) << "no stretch complete";
  health.finish();
  ASSERT_EQ(health.events().size(), 1U);
  EXPECT_EQ(health.events()[0].problem, HealthProblem::non_finite);
  EXPECT_EQ(health.events()[0].stretch_s, 0.5);

  ChannelHealth short_one(2, kRate);
  EXPECT_TRUE(feed(short_one, sines(2, 0.2, 0.0)).empty()) << "0.2 s is too short to judge";
  EXPECT_EQ(short_one.channel(0).samples, static_cast<std::int64_t>(0.2 * kRate));
}

TEST(ChannelHealth, IgnoresRunsOfAnotherShapeAndRejectsBadSettings) {
  ChannelHealth health(2, kRate);
  const testing::Recording three = sines(3, 1.0);
  const std::array<double, 3> zeros{};
  health.observe(
      ChannelRun{three.interleaved.data(), 100, 3, 0, zeros.data(), zeros.data(), zeros.data()});
  health.observe(ChannelRun{nullptr, 100, 2, 0, zeros.data(), zeros.data(), zeros.data()});
  EXPECT_EQ(health.channel(0).samples, 0);
  EXPECT_THROW(ChannelHealth(0, kRate), std::invalid_argument);
  EXPECT_THROW(ChannelHealth(2, 0.0), std::invalid_argument);
  ChannelHealthSettings bad;
  bad.stretch_s = 0.0;
  EXPECT_THROW(ChannelHealth(2, kRate, bad), std::invalid_argument);
}

// Every problem on its own channel at once, the block and frame boundaries falling anywhere in
// the stretches: each channel raises its own problem and counts its own samples.
TEST(ChannelHealth, EachChannelRaisesItsOwnProblem) {
  testing::Recording recording = sines(4, 5.3);
  std::int64_t clipped = 0;
  std::int64_t absurd = 0;
  for (std::size_t n = 0; n < recording.frames(); ++n) {
    if (n >= 9000 && n < 9700) at(recording, n, 0) = n % 2 == 0 ? kNaN : kInf;
    at(recording, n, 1) += 0.5F;                                   // DC offset
    at(recording, n, 2) = n < 20000 ? 0.0F : at(recording, n, 2);  // silent, then not
    if (n % 50 == 0) {                                             // clipped, absurd
      at(recording, n, 3) = n % 100 == 0 ? 1.0F : -6.0F;
      ++clipped;
      absurd += n % 100 != 0;
    }
  }
  ChannelHealth health(4, kRate);
  const std::vector<HealthEvent> events = feed(health, recording, 700);
  EXPECT_GE(events.size(), 4U);  // each channel's problem raised
  for (int c = 0; c < 4; ++c)
    EXPECT_EQ(health.channel(c).samples, static_cast<std::int64_t>(recording.frames())) << c;
  EXPECT_EQ(health.channel(0).non_finite_samples, 700);
  EXPECT_EQ(health.channel(3).clipped_samples, clipped);
  EXPECT_EQ(health.channel(3).absurd_samples, absurd);
  EXPECT_TRUE(has_problem(health.channel(1).problems_seen, HealthProblem::dc_offset));
  EXPECT_TRUE(has_problem(health.channel(2).problems_seen, HealthProblem::silent));
  EXPECT_TRUE(has_problem(health.channel(3).problems_seen, HealthProblem::absurd_level));
  EXPECT_EQ(count(events, 0, HealthProblem::non_finite), 1);
}

// The node counts and raises on the samples as they came, and its FFTs never see a NaN: an
// all-NaN channel does not stop the others' level meter nor crash anything.
TEST(ChannelHealth, TheNodePipelineCountsPerChannelAndRaisesOnce) {
  constexpr double kNodeRate = 48000.0;
  const ArrayGeometry geometry = testing::tetrahedron();
  NodePipeline pipeline(geometry, 0, DoaParams{}, kNodeRate, 343.0);
  testing::Recording recording =
      testing::silent_recording(4, static_cast<std::size_t>(3.0 * kNodeRate));
  testing::add_sensor_noise(recording, kNodeRate, 200.0, 8000.0, 0.05, 3);
  for (std::size_t n = 0; n < recording.frames(); ++n) at(recording, n, 2) = kNaN;
  std::vector<DoaMeasurement> out;
  int raised = 0;
  for (std::size_t first = 0; first < recording.frames(); first += 2400) {
    pipeline.process(recording.view(first, std::min<std::size_t>(2400, recording.frames() - first)),
                     out);
    for (const HealthEvent& event : pipeline.health().events()) {
      EXPECT_EQ(event.channel, 2);
      EXPECT_EQ(event.problem, HealthProblem::non_finite);
      ++raised;
    }
  }
  pipeline.finish();
  EXPECT_EQ(raised, 1);
  EXPECT_EQ(pipeline.health().channel(2).non_finite_samples,
            static_cast<std::int64_t>(recording.frames()));
  EXPECT_EQ(pipeline.diagnostics().non_finite_samples,
            static_cast<std::int64_t>(recording.frames()));
  EXPECT_TRUE(std::isfinite(pipeline.diagnostics().level_dbfs));
  EXPECT_GT(pipeline.diagnostics().level_dbfs, -40.0);
  EXPECT_GT(pipeline.diagnostics().frames_processed, 40);
  EXPECT_TRUE(out.empty());
}

}  // namespace
}  // namespace dronetrack::doa::channel_health_test
