// ArrayHealth with known answers. First on the pair peaks a tetrahedron's GCC would give for
// plane waves from known directions (exact TDOAs plus a few microseconds of noise), with one
// fault injected; then the whole node on synthetic audio: a flipped channel, a dead one, +6 dB
// on one (and the same with its calibrated gain, which is quiet), a skewed channel, a clean array.
#include "doa/array_health.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <ostream>
#include <random>
#include <vector>

#include "doa/node_pipeline.hpp"
#include "tests/doa/synthetic_audio.hpp"

namespace dronetrack::doa {
namespace {

using testing::tetrahedron;

constexpr double kSpeed = 343.0;
constexpr double kHop = 0.05;

Eigen::Vector3d direction_deg(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * std::numbers::pi / 180.0;
  const double el = elevation_deg * std::numbers::pi / 180.0;
  return {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
}

// A source circling the array (a turn every 12 s, elevation 10-40 deg), one frame per hop.
struct Scene {
  ArrayGeometry geometry = tetrahedron();
  std::vector<double> channel_delay_s = std::vector<double>(4, 0.0);
  std::vector<double> channel_power = std::vector<double>(4, 1e-4);
  std::vector<double> pair_sign = std::vector<double>(6, 1.0);
  std::vector<double> pair_peak = std::vector<double>(6, 0.6);
  std::vector<double> pair_lag_error_s = std::vector<double>(6, 0.0);
  double noise_s = 2e-6;
  double speed_mps = kSpeed;  // the air's; the node assumes kSpeed
  unsigned seed = 1;
  std::array<int, 2> swapped{-1, -1};  // two mics recorded on each other's channel
  // The source's direction at a time: by default circling the array.
  std::function<Eigen::Vector3d(double)> direction = [](double time_s) {
    return direction_deg(30.0 * time_s, 25.0 + 15.0 * std::sin(0.4 * time_s));
  };

  // The mic whose sound channel `c` records.
  std::size_t heard_by(int c) const {
    return static_cast<std::size_t>(c == swapped[0]   ? swapped[1]
                                    : c == swapped[1] ? swapped[0]
                                                      : c);
  }

  // Runs `seconds` and returns every event raised.
  std::vector<ArrayHealthEvent> run(ArrayHealth& health, double seconds) const {
    std::mt19937 random(seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    std::vector<ArrayHealthEvent> events;
    std::vector<PairPeak> pairs(6);
    for (int frame = 0; frame * kHop < seconds; ++frame) {
      const double time_s = frame * kHop;
      const Eigen::Vector3d u = direction(time_s);
      int p = 0;
      for (int i = 0; i < 4; ++i) {
        for (int j = i + 1; j < 4; ++j, ++p) {
          const auto pair = static_cast<std::size_t>(p);
          const double tdoa_s =
              (geometry.mics_m[heard_by(j)] - geometry.mics_m[heard_by(i)]).dot(u) / speed_mps +
              channel_delay_s[static_cast<std::size_t>(i)] -
              channel_delay_s[static_cast<std::size_t>(j)];
          // A band-pass correlation: main lobe and a side lobe of the other sign a third as large.
          const double main = pair_sign[pair] * pair_peak[pair];
          const double side = -main / 3.0;
          pairs[pair] = {tdoa_s + pair_lag_error_s[pair] + noise_s * normal(random),
                         std::max(main, side), std::min(main, side)};
        }
      }
      health.observe(time_s, channel_power, pairs, true, true);
      events.insert(events.end(), health.events().begin(), health.events().end());
      health.clear_events();
    }
    return events;
  }
};

ArrayHealth make_health(const Scene& scene, const ArrayHealthSettings& settings = {}) {
  return ArrayHealth(scene.geometry, kSpeed, kHop, settings);
}

// Pairs in lexicographic order: 01 02 03 12 13 23.
constexpr std::array<std::array<int, 2>, 6> kPairs = {
    {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};

struct Raised {
  int channel = 0;
  ArrayProblem problem = ArrayProblem::level_imbalance;
  bool operator==(const Raised&) const = default;
};
void PrintTo(const Raised& raised, std::ostream* out) {
  *out << "channel " << raised.channel << " " << to_string(raised.problem);
}
std::vector<Raised> raised(const std::vector<ArrayHealthEvent>& events) {
  std::vector<Raised> out;
  for (const ArrayHealthEvent& event : events) out.push_back({event.channel, event.problem});
  return out;
}
std::vector<Raised> only(int channel, ArrayProblem problem) { return {{channel, problem}}; }

TEST(ArrayHealth, CorrelationExtremes) {
  const std::vector<double> grid = {0.1, -0.3, 0.7, 0.2};
  EXPECT_DOUBLE_EQ(correlation_extremes(grid).highest, 0.7);
  EXPECT_DOUBLE_EQ(correlation_extremes(grid).lowest, -0.3);
  const std::vector<double> positive = {0.1, 0.3};
  EXPECT_DOUBLE_EQ(correlation_extremes(positive).lowest, 0.0);
  EXPECT_DOUBLE_EQ(correlation_extremes({}).highest, 0.0);
}

TEST(ArrayHealth, CleanArrayRaisesNothingAndClosesToNoise) {
  const Scene scene;
  ArrayHealth health = make_health(scene);
  EXPECT_TRUE(scene.run(health, 60.0).empty());
  EXPECT_LT(health.closure_residual_us(), 3.0);
  EXPECT_LT(health.fit_residual_us(), 3.0);
  for (const ArrayChannelHealth& channel : health.channel_health()) {
    EXPECT_EQ(channel.problems_seen, 0);
    EXPECT_NEAR(channel.level_offset_db, 0.0, 1e-9);
    EXPECT_LT(std::fabs(channel.delay_offset_us), 2.0);
  }
}

TEST(ArrayHealth, FlippedChannelNamedAlone) {
  Scene scene;
  for (std::size_t p = 0; p < kPairs.size(); ++p)
    if (kPairs[p][0] == 2 || kPairs[p][1] == 2) scene.pair_sign[p] = -1.0;
  ArrayHealth health = make_health(scene);
  const auto events = raised(scene.run(health, 5.0));
  EXPECT_EQ(events, only(2, ArrayProblem::polarity_flipped));
  // Its triples give no lags to add, the others close.
  EXPECT_LT(health.closure_residual_us(), 3.0);
}

TEST(ArrayHealth, IncoherentChannelIsDead) {
  Scene scene;
  for (std::size_t p = 0; p < kPairs.size(); ++p)
    if (kPairs[p][0] == 3 || kPairs[p][1] == 3) scene.pair_peak[p] = 0.08;
  ArrayHealth health = make_health(scene);
  const auto events = raised(scene.run(health, 5.0));
  EXPECT_EQ(events, only(3, ArrayProblem::dead));
}

TEST(ArrayHealth, QuietChannelIsDeadAndLoudOneImbalanced) {
  Scene scene;
  scene.channel_power[1] *= std::pow(10.0, 6.0 / 10.0);  // +6 dB
  scene.channel_power[3] *= 1e-3;                        // -30 dB
  ArrayHealth health = make_health(scene);
  const auto events = raised(scene.run(health, 5.0));
  const std::vector<Raised> expected = {{1, ArrayProblem::level_imbalance},
                                        {3, ArrayProblem::dead}};
  EXPECT_EQ(events, expected);
  // Median of 4 levels: the middle two, both unchanged.
  EXPECT_NEAR(health.channel_health()[1].level_offset_db, 6.0, 1e-9);
  EXPECT_NEAR(health.channel_health()[3].level_offset_db, -30.0, 1e-9);
}

// A tetrahedron with no symmetry (mics at different radii and heights): every swap of two of its
// channels leaves a plane-wave misfit.
ArrayGeometry irregular_tetrahedron() {
  ArrayGeometry geometry = tetrahedron();
  geometry.mics_m = {{0.0, 0.0, 0.6}, {0.55, 0.0, -0.1}, {-0.2, 0.45, -0.2}, {-0.3, -0.35, -0.15}};
  return geometry;
}

// The source staying near one direction (a few degrees either way).
Scene source_staying_near(double azimuth_deg, double elevation_deg) {
  Scene scene;
  scene.geometry = irregular_tetrahedron();
  scene.direction = [=](double time_s) {
    return direction_deg(azimuth_deg + 5.0 * std::sin(0.3 * time_s),
                         elevation_deg + 3.0 * std::sin(0.2 * time_s));
  };
  return scene;
}

// The delay fit names a skewed channel and measures its skew; closure cannot (a pure delay
// cancels in every closure sum). At the default settings it resolves one sample at 48 kHz, on
// a bottom mic and on the top one, of the regular and the irregular array.
void expect_skew_found(double skew_s, int channel, const ArrayGeometry& geometry) {
  Scene scene;
  scene.geometry = geometry;
  scene.channel_delay_s[static_cast<std::size_t>(channel)] = skew_s;
  ArrayHealth health = make_health(scene);
  const auto events = raised(scene.run(health, 40.0));
  EXPECT_EQ(events, only(channel, ArrayProblem::skew)) << "skew " << skew_s << " on " << channel;
  const ArrayChannelHealth& skewed = health.channel_health()[static_cast<std::size_t>(channel)];
  EXPECT_NEAR(skewed.delay_offset_us, 1e6 * skew_s, 3.0);
  // The recovered delay within its reported std (3 sigma), which is a fraction of a sample.
  EXPECT_LT(std::fabs(skewed.delay_offset_us - 1e6 * skew_s), 3.0 * skewed.delay_std_us + 0.5);
  EXPECT_LT(skewed.delay_std_us, 5.0);
  for (int c = 0; c < 4; ++c) {
    if (c == channel) continue;
    EXPECT_LT(std::fabs(health.channel_health()[static_cast<std::size_t>(c)].delay_offset_us), 3.0);
  }
  EXPECT_LT(health.closure_residual_us(), 3.0);
  EXPECT_GT(health.fit_residual_us(), 3.0);
}

TEST(ArrayHealth, SkewedChannelNamedByTheDelayFit) {
  expect_skew_found(0.2e-3, 2, tetrahedron());
  for (int channel : {0, 2}) {
    expect_skew_found(1.0 / 48000.0, channel, tetrahedron());  // one sample at 48 kHz
    expect_skew_found(1.0 / 48000.0, channel, irregular_tetrahedron());
  }
}

// Air 2 % faster than the node assumes (12 K warmer) scales every slowness, which a top-mic
// delay mimics from any one elevation: the fit's scale takes it, no channel is skewed.
TEST(ArrayHealth, SpeedOfSoundOffIsNotASkew) {
  for (const ArrayGeometry& geometry : {tetrahedron(), irregular_tetrahedron()}) {
    Scene scene;
    scene.geometry = geometry;
    scene.speed_mps = 1.02 * kSpeed;
    ArrayHealth health = make_health(scene);
    EXPECT_TRUE(scene.run(health, 60.0).empty());
    EXPECT_NEAR(health.slowness_scale_error(), 1.0 / 1.02 - 1.0, 0.002);
    for (const ArrayChannelHealth& channel : health.channel_health())
      EXPECT_LT(std::fabs(channel.delay_offset_us), 3.0);
  }
}

// A source that stays near one direction leaves a channel's delay indistinguishable from a turn
// of the direction and from the slowness's scale: unexcited, so not judged, even at 0.2 ms.
TEST(ArrayHealth, SkewFromTooFewDirectionsIsNotJudged) {
  for (int channel : {0, 2}) {
    Scene scene = source_staying_near(100.0, 30.0);
    scene.geometry = tetrahedron();
    scene.channel_delay_s[static_cast<std::size_t>(channel)] = 0.2e-3;
    ArrayHealth health = make_health(scene);
    EXPECT_TRUE(scene.run(health, 60.0).empty()) << channel;
    EXPECT_GT(health.delay_sectors_seen(), 0);
    EXPECT_LT(health.delay_sectors_seen(), ArrayHealthSettings{}.min_skew_sectors);
    for (const ArrayChannelHealth& health_of : health.channel_health())
      EXPECT_FALSE(std::isfinite(health_of.delay_std_us));
  }
}

TEST(ArrayHealth, ChannelWhosePairsDisagreeFailsClosure) {
  Scene scene;
  // Channel 1's three pairs each on a wrong cycle of its own: every triple holding it fails.
  scene.pair_lag_error_s = {60e-6, 0.0, 0.0, 30e-6, 90e-6, 0.0};
  ArrayHealth health = make_health(scene);
  const auto events = raised(scene.run(health, 5.0));
  EXPECT_EQ(events, only(1, ArrayProblem::closure));
  // Triples 012: 60 + 30 = 90, 013: 60 + 90 = 150, 123: 30 - 90 = -60 us.
  EXPECT_NEAR(health.closure_residual_us(), 150.0, 3.0);
}

TEST(ArrayHealth, ProblemRaisedOnceWhileItLasts) {
  Scene scene;
  scene.channel_power[0] *= 10.0;
  ArrayHealth health = make_health(scene);
  EXPECT_EQ(scene.run(health, 60.0).size(), 1U);
  EXPECT_TRUE(has_problem(health.channel_health()[0].problems, ArrayProblem::level_imbalance));
}

TEST(ArrayHealth, RejectsBadSettingsByName) {
  ArrayHealthSettings settings;
  settings.imbalance_db = -1.0;
  try {
    ArrayHealth health(tetrahedron(), kSpeed, kHop, settings);
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("imbalance_db"), std::string::npos);
  }
}

// Two channels wired to each other's inputs keep every closure sum (a relabelling), so only the
// plane-wave fit can name them: every swap of the irregular array, the source circling.
TEST(ArrayHealth, SwappedChannelsNamedTogether) {
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      Scene scene;
      scene.geometry = irregular_tetrahedron();
      scene.swapped = {a, b};
      ArrayHealth health = make_health(scene);
      ASSERT_TRUE(health.swap_observable(a, b)) << health.swap_signature_us(a, b);
      const auto events = scene.run(health, 30.0);
      ASSERT_EQ(raised(events), only(a, ArrayProblem::swapped)) << a << b;
      EXPECT_EQ(events[0].other_channel, b);
      EXPECT_LT(events[0].swapped_misfit_us, 3.0);
      EXPECT_GT(events[0].wired_misfit_us, 2.0 * events[0].swapped_misfit_us);
      EXPECT_LT(health.closure_residual_us(), 3.0);
      for (int c = 0; c < 4; ++c)
        EXPECT_EQ(has_problem(health.channel_health()[static_cast<std::size_t>(c)].problems,
                              ArrayProblem::swapped),
                  c == a || c == b);
    }
  }
}

// The same with the source staying in one region of the sky, for several regions: a swap's
// misfit changes with the direction, but is well over the evidence bar at these. (Near this
// array's zenith swapping 1 and 3 leaves almost none, and the check says nothing there.)
TEST(ArrayHealth, SwappedChannelsNamedFromSeveralDirections) {
  Scene near_zenith = source_staying_near(45.0, 80.0);
  near_zenith.swapped = {1, 3};
  ArrayHealth quiet = make_health(near_zenith);
  EXPECT_TRUE(near_zenith.run(quiet, 30.0).empty());
  for (const auto& [azimuth_deg, elevation_deg] :
       {std::pair{0.0, 10.0}, {100.0, 30.0}, {200.0, 60.0}, {290.0, 5.0}, {160.0, -20.0}}) {
    Scene scene = source_staying_near(azimuth_deg, elevation_deg);
    scene.swapped = {1, 3};
    ArrayHealth health = make_health(scene);
    EXPECT_EQ(raised(scene.run(health, 30.0)), only(1, ArrayProblem::swapped))
        << "azimuth " << azimuth_deg << " elevation " << elevation_deg;
  }
}

TEST(ArrayHealth, CleanIrregularArrayRaisesNoSwap) {
  for (unsigned seed : {1U, 2U, 3U}) {
    Scene scene;
    scene.geometry = irregular_tetrahedron();
    scene.seed = seed;
    scene.noise_s = 5e-6;
    ArrayHealth health = make_health(scene);
    EXPECT_TRUE(scene.run(health, 60.0).empty()) << seed;
  }
}

// A regular tetrahedron's every swap is a mirror of it: the swapped array hears exactly what the
// true one hears of the mirror image of the world, so no check at the node can see it. The check
// says so, and says nothing.
TEST(ArrayHealth, SwapOfARegularTetrahedronIsUnobservable) {
  Scene scene;
  scene.swapped = {0, 2};
  ArrayHealth health = make_health(scene);
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) {
      EXPECT_FALSE(health.swap_observable(a, b));
      EXPECT_LT(health.swap_signature_us(a, b), 0.5);
    }
  EXPECT_TRUE(scene.run(health, 30.0).empty());
  EXPECT_LT(health.fit_residual_us(), 3.0);
}

// The node on audio: a band-noise source from a direction that steps every second around the
// array, sensor noise 20 dB under it in band.
constexpr double kRate = 16000.0;

struct AudioFault {
  int flipped = -1;
  int dead = -1;
  int louder = -1;  // +6 dB
  int skewed = -1;  // 0.2 ms late
  bool calibrated_gain = false;
  std::array<int, 2> swapped{-1, -1};  // recorded on each other's channel
  bool irregular = false;              // irregular_tetrahedron() instead of the regular one
};

std::vector<ArrayHealthEvent> run_node(const AudioFault& fault, NodePipeline** keep = nullptr) {
  ArrayGeometry geometry = fault.irregular ? irregular_tetrahedron() : tetrahedron();
  if (fault.calibrated_gain && fault.louder >= 0) {
    geometry.channel_gain_db.assign(4, 0.0);
    geometry.channel_gain_db[static_cast<std::size_t>(fault.louder)] = 6.0;
  }
  DoaParams params;
  params.bands_hz = {{500.0, 3000.0}};
  static std::unique_ptr<NodePipeline> pipeline;
  pipeline = std::make_unique<NodePipeline>(geometry, 0, params, kRate, kSpeed);
  std::vector<ArrayHealthEvent> events;
  std::vector<DoaMeasurement> doas;
  const int segment = static_cast<int>(kRate);  // 1 s per direction
  for (int s = 0; s < 30; ++s) {
    testing::Recording recording = testing::silent_recording(4, static_cast<std::size_t>(segment));
    const testing::BandNoise source(segment, kRate, 500.0, 3000.0, 100U + static_cast<unsigned>(s));
    const Eigen::Vector3d u = direction_deg(37.0 * s, 10.0 + 6.0 * (s % 9));
    std::vector<double> delays = testing::plane_wave_delays(geometry, u, kSpeed);
    if (fault.skewed >= 0) delays[static_cast<std::size_t>(fault.skewed)] += 0.2e-3;
    for (int mic = 0; mic < 4; ++mic) {
      double rms = 0.1;
      if (mic == fault.louder) rms *= 2.0;
      if (mic == fault.flipped) rms = -rms;
      if (mic == fault.dead) rms = 0.0;
      const int heard = mic == fault.swapped[0]   ? fault.swapped[1]
                        : mic == fault.swapped[1] ? fault.swapped[0]
                                                  : mic;
      recording.add(mic, source.delayed(delays[static_cast<std::size_t>(heard)], rms));
    }
    testing::add_sensor_noise(recording, kRate, 100.0, 7900.0, 0.02, 7U + static_cast<unsigned>(s));
    doas.clear();
    pipeline->process({static_cast<std::int64_t>(s) * segment, 4, recording.frames(),
                       recording.interleaved.data()},
                      doas);
    events.insert(events.end(), pipeline->array_health().events().begin(),
                  pipeline->array_health().events().end());
  }
  if (keep != nullptr) *keep = pipeline.get();
  return events;
}

TEST(ArrayHealthNode, CleanAudioRaisesNothing) {
  NodePipeline* pipeline = nullptr;
  EXPECT_TRUE(raised(run_node({}, &pipeline)).empty());
  EXPECT_LT(pipeline->array_health().closure_residual_us(), 5.0);
  for (const ArrayChannelHealth& channel : pipeline->array_health().channel_health())
    EXPECT_LT(std::fabs(channel.level_offset_db), 1.0);
}

TEST(ArrayHealthNode, FlippedChannelTwo) {
  AudioFault fault;
  fault.flipped = 2;
  const auto events = raised(run_node(fault));
  EXPECT_EQ(events, only(2, ArrayProblem::polarity_flipped));
}

TEST(ArrayHealthNode, DeadChannel) {
  AudioFault fault;
  fault.dead = 1;
  NodePipeline* pipeline = nullptr;
  const auto events = raised(run_node(fault, &pipeline));
  EXPECT_EQ(events, only(1, ArrayProblem::dead));
  // Its sensor noise alone: 19 dB under the others in band.
  EXPECT_LT(pipeline->array_health().channel_health()[1].level_offset_db, -15.0);
}

TEST(ArrayHealthNode, SixDecibelsLouderChannelUnlessCalibrated) {
  AudioFault fault;
  fault.louder = 3;
  NodePipeline* pipeline = nullptr;
  const auto events = raised(run_node(fault, &pipeline));
  EXPECT_EQ(events, only(3, ArrayProblem::level_imbalance));
  EXPECT_NEAR(pipeline->array_health().channel_health()[3].level_offset_db, 6.0, 0.5);
  fault.calibrated_gain = true;
  EXPECT_TRUE(raised(run_node(fault, &pipeline)).empty());
  EXPECT_NEAR(pipeline->array_health().channel_health()[3].level_offset_db, 0.0, 0.5);
}

TEST(ArrayHealthNode, SwappedChannelsNamedOnAnIrregularArray) {
  AudioFault fault;
  fault.irregular = true;
  EXPECT_TRUE(raised(run_node(fault)).empty());
  fault.swapped = {0, 2};
  const auto events = run_node(fault);
  ASSERT_EQ(raised(events), only(0, ArrayProblem::swapped));
  EXPECT_EQ(events[0].other_channel, 2);
}

TEST(ArrayHealthNode, SkewedChannelNamed) {
  AudioFault fault;
  fault.skewed = 0;
  NodePipeline* pipeline = nullptr;
  const auto events = raised(run_node(fault, &pipeline));
  EXPECT_EQ(events, only(0, ArrayProblem::skew));
  EXPECT_NEAR(pipeline->array_health().channel_health()[0].delay_offset_us, 200.0, 10.0);
}

}  // namespace
}  // namespace dronetrack::doa
