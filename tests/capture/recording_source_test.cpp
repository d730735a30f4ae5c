// RecordingSource against files written here with libsndfile: each format, with a known
// multichannel signal, must come back sample for sample (within the format's quantisation).
#include "capture/recording_source.hpp"

#include "capture/block_mapping.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sndfile.h>

namespace dronetrack::capture {
namespace {

namespace fs = std::filesystem;

constexpr int kRateHz = 16000;

// Channel c carries a sine of its own frequency and amplitude, so a swapped channel or a frame
// shifted by one sample shows up as a large error.
float known_signal(std::int64_t frame, int channel) {
  const double frequency_hz = 220.0 * (channel + 1) + 17.0;
  const double amplitude = 0.8 - 0.1 * channel;
  return static_cast<float>(
      amplitude * std::sin(2.0 * M_PI * frequency_hz * static_cast<double>(frame) / kRateHz));
}

std::vector<float> known_interleaved(std::int64_t frames, int channels) {
  std::vector<float> samples(static_cast<std::size_t>(frames * channels));
  for (std::int64_t frame = 0; frame < frames; ++frame) {
    for (int channel = 0; channel < channels; ++channel) {
      samples[static_cast<std::size_t>(frame * channels + channel)] = known_signal(frame, channel);
    }
  }
  return samples;
}

void write_file(const fs::path& path, int format, int channels, const std::vector<float>& data) {
  SF_INFO info{};
  info.samplerate = kRateHz;
  info.channels = channels;
  info.format = format;
  SNDFILE* file = sf_open(path.c_str(), SFM_WRITE, &info);
  ASSERT_NE(file, nullptr) << sf_strerror(nullptr);
  // Float WAVs must keep NaN/Inf/over-range values as written, so no clipping on write.
  const auto frames = static_cast<sf_count_t>(data.size() / static_cast<std::size_t>(channels));
  ASSERT_EQ(sf_writef_float(file, data.data(), frames), frames);
  sf_close(file);
}

class RecordingSourceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    directory_ = fs::temp_directory_path() /
                 ("dronetrack_capture_test_" + std::to_string(::getpid()) + "_" +
                  ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(directory_);
  }
  void TearDown() override { fs::remove_all(directory_); }
  fs::path path(const std::string& name) const { return directory_ / name; }

  fs::path directory_;
};

std::string error_of(const fs::path& file, std::vector<int> channel_map, std::size_t block) {
  try {
    RecordingSource source(file, std::move(channel_map), block);
  } catch (const std::runtime_error& error) {
    return error.what();
  }
  return "(no error)";
}

// libsndfile writes floats to PCM scaled by 2^(bits-1) - 1 but reads PCM back scaled by
// 2^-(bits-1), so a round trip has a gain of (1 - 2^-(bits-1)) on top of the half-step
// rounding: at amplitude 0.8 that is another 0.8 step. Allow 1.5 steps.
constexpr double kPcm16Tolerance = 1.5 / 32768.0;
constexpr double kPcm24Tolerance = 1.5 / 8388608.0 + 1e-7;

struct FormatCase {
  const char* name;
  int format;
  double tolerance;
};

class EachFormat : public RecordingSourceTest, public ::testing::WithParamInterface<FormatCase> {};

TEST_P(EachFormat, ReturnsTheWrittenSamplesWithTimestampsAcrossBlocks) {
  const FormatCase& format = GetParam();
  constexpr int kChannels = 4;
  constexpr std::int64_t kFrames = 1000;  // 1000 = 3 x 300 + a short block of 100
  constexpr std::size_t kBlock = 300;
  const fs::path file = path("signal");
  write_file(file, format.format, kChannels, known_interleaved(kFrames, kChannels));

  RecordingSource source(file, {}, kBlock);
  EXPECT_EQ(source.channels(), kChannels);
  EXPECT_EQ(source.sample_rate_hz(), kRateHz);
  EXPECT_EQ(source.total_frames(), kFrames);

  doa::AudioBlockView block;
  std::int64_t expected_first = 0;
  std::vector<std::size_t> block_sizes;
  double worst_error = 0.0;
  const float* first_buffer = nullptr;
  while (source.next(block)) {
    // Streaming reuses one buffer: a new one per block would be an allocation per block.
    if (first_buffer == nullptr) first_buffer = block.interleaved;
    EXPECT_EQ(block.interleaved, first_buffer);
    EXPECT_EQ(block.first_sample, expected_first);
    EXPECT_EQ(block.channels, kChannels);
    block_sizes.push_back(block.frames);
    for (std::size_t frame = 0; frame < block.frames; ++frame) {
      for (int channel = 0; channel < kChannels; ++channel) {
        const double error =
            std::fabs(block.sample(frame, channel) -
                      known_signal(block.first_sample + static_cast<std::int64_t>(frame), channel));
        worst_error = std::max(worst_error, error);
      }
    }
    expected_first += static_cast<std::int64_t>(block.frames);
  }
  EXPECT_EQ(block_sizes, (std::vector<std::size_t>{300, 300, 300, 100}));
  EXPECT_EQ(expected_first, kFrames);
  EXPECT_LE(worst_error, format.tolerance) << format.name;
  EXPECT_FALSE(source.truncated());
  EXPECT_FALSE(source.next(block)) << "stays ended";
}

INSTANTIATE_TEST_SUITE_P(
    Formats, EachFormat,
    ::testing::Values(FormatCase{"wav_pcm16", SF_FORMAT_WAV | SF_FORMAT_PCM_16, kPcm16Tolerance},
                      FormatCase{"wav_pcm24", SF_FORMAT_WAV | SF_FORMAT_PCM_24, kPcm24Tolerance},
                      FormatCase{"wav_pcm32", SF_FORMAT_WAV | SF_FORMAT_PCM_32, 1e-7},
                      FormatCase{"wav_float", SF_FORMAT_WAV | SF_FORMAT_FLOAT, 0.0},
                      FormatCase{"flac_pcm16", SF_FORMAT_FLAC | SF_FORMAT_PCM_16, kPcm16Tolerance},
                      FormatCase{"flac_pcm24", SF_FORMAT_FLAC | SF_FORMAT_PCM_24, kPcm24Tolerance}),
    [](const auto& param_info) { return std::string(param_info.param.name); });

TEST_F(RecordingSourceTest, Pcm16IntegersReadBackExactly) {
  // Integer samples written as integers: each must read back as exactly value / 32768.
  std::vector<short> values;
  for (int value = -32768; value <= 32767; value += 97) values.push_back(static_cast<short>(value));
  values.push_back(32767);
  const fs::path file = path("ints.wav");
  SF_INFO info{};
  info.samplerate = kRateHz;
  info.channels = 1;
  info.format = SF_FORMAT_WAV | SF_FORMAT_PCM_16;
  SNDFILE* handle = sf_open(file.c_str(), SFM_WRITE, &info);
  ASSERT_NE(handle, nullptr);
  ASSERT_EQ(sf_writef_short(handle, values.data(), static_cast<sf_count_t>(values.size())),
            static_cast<sf_count_t>(values.size()));
  sf_close(handle);

  RecordingSource source(file, {}, 100);
  doa::AudioBlockView block;
  std::size_t index = 0;
  while (source.next(block)) {
    for (std::size_t frame = 0; frame < block.frames; ++frame, ++index) {
      ASSERT_EQ(block.sample(frame, 0), static_cast<float>(values[index]) / 32768.0F)
          << "sample " << index;
    }
  }
  EXPECT_EQ(index, values.size());
}

TEST_F(RecordingSourceTest, ChannelMapReordersAndSelectsChannels) {
  const fs::path file = path("four.wav");
  write_file(file, SF_FORMAT_WAV | SF_FORMAT_FLOAT, 4, known_interleaved(500, 4));
  // Three mics: mic 0 on file channel 3, mic 1 on channel 0, mic 2 on channel 2 (1 unused).
  const std::vector<int> channel_map{3, 0, 2};
  RecordingSource source(file, channel_map, 128);
  EXPECT_EQ(source.channels(), 3);
  doa::AudioBlockView block;
  std::int64_t frames_seen = 0;
  while (source.next(block)) {
    ASSERT_EQ(block.channels, 3);
    for (std::size_t frame = 0; frame < block.frames; ++frame) {
      const std::int64_t index = block.first_sample + static_cast<std::int64_t>(frame);
      for (int mic = 0; mic < 3; ++mic) {
        ASSERT_EQ(block.sample(frame, mic), known_signal(index, channel_map[mic]))
            << "mic " << mic << " frame " << index;
      }
    }
    frames_seen += static_cast<std::int64_t>(block.frames);
  }
  EXPECT_EQ(frames_seen, 500);
}

TEST_F(RecordingSourceTest, BlockLargerThanFileGivesOneShortBlock) {
  const fs::path file = path("short.wav");
  write_file(file, SF_FORMAT_WAV | SF_FORMAT_PCM_16, 2, known_interleaved(37, 2));
  RecordingSource source(file, {}, 4096);
  doa::AudioBlockView block;
  ASSERT_TRUE(source.next(block));
  EXPECT_EQ(block.first_sample, 0);
  EXPECT_EQ(block.frames, 37U);
  EXPECT_FALSE(source.next(block));
}

// The source delivers what the file holds; judging it (and replacing NaN/Inf by 0 before the
// FFTs) is the node's job (doa/channel_health.hpp), which must see the bad samples to say so.
TEST_F(RecordingSourceTest, NonFiniteSamplesPassUnchanged) {
  constexpr int kChannels = 2;
  std::vector<float> data = known_interleaved(64, kChannels);
  data[10] = std::numeric_limits<float>::quiet_NaN();   // frame 5, channel 0
  data[33] = std::numeric_limits<float>::infinity();    // frame 16, channel 1
  data[100] = -std::numeric_limits<float>::infinity();  // frame 50, channel 0
  write_file(path("nan.wav"), SF_FORMAT_WAV | SF_FORMAT_FLOAT, kChannels, data);

  RecordingSource source(path("nan.wav"), {}, 32);
  doa::AudioBlockView block;
  std::int64_t delivered = 0;
  while (source.next(block)) {
    for (std::size_t frame = 0; frame < block.frames; ++frame) {
      for (int channel = 0; channel < kChannels; ++channel) {
        const float sample = block.sample(frame, channel);
        const std::size_t index = static_cast<std::size_t>(block.first_sample) * kChannels +
                                  frame * kChannels + static_cast<std::size_t>(channel);
        if (index == 10) {
          EXPECT_TRUE(std::isnan(sample));
        } else {
          EXPECT_EQ(sample, data[index]) << "sample " << index;
        }
      }
    }
    // The level meter reads the finite samples only.
    EXPECT_TRUE(std::isfinite(source.counters().peak_level_dbfs));
    EXPECT_TRUE(std::isfinite(source.counters().rms_level_dbfs));
    EXPECT_LT(source.counters().peak_level_dbfs, 0.0);
    delivered += static_cast<std::int64_t>(block.frames);
  }
  EXPECT_EQ(delivered, 64);
}

TEST_F(RecordingSourceTest, LevelsAreMeasuredAndOverRangeSamplesKept) {
  constexpr int kChannels = 2;
  std::vector<float> data(100 * kChannels, 0.5F);  // a constant 0.5: -6.02 dBFS peak and rms
  data[7] = 1.0F;
  data[150] = 1.5F;  // over full scale, as float WAVs can hold
  write_file(path("clip.wav"), SF_FORMAT_WAV | SF_FORMAT_FLOAT, kChannels, data);

  RecordingSource source(path("clip.wav"), {}, 50);
  doa::AudioBlockView block;
  ASSERT_TRUE(source.next(block));  // frames 0..49: samples 0..99
  EXPECT_NEAR(source.counters().peak_level_dbfs, 0.0, 1e-9);
  ASSERT_TRUE(source.next(block));  // samples 100..199
  EXPECT_EQ(block.sample(25, 0), 1.5F) << "not clipped on the way";
  EXPECT_NEAR(source.counters().peak_level_dbfs, 20.0 * std::log10(1.5), 1e-6);
  const double rms = std::sqrt((99 * 0.25 + 1.5 * 1.5) / 100.0);
  EXPECT_NEAR(source.counters().rms_level_dbfs, 20.0 * std::log10(rms), 1e-6);
  EXPECT_FALSE(source.next(block));
}

TEST(MeasureLevels, FiniteSamplesOnlyAtEveryPositionOfTheBlock) {
  // 8 lanes and a tail: the non-finite samples and the peak in lanes and in the tail; an
  // over-range 3.0 in a lane, -2.5 (the largest magnitude of the tail) last.
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  for (const std::size_t count : {std::size_t{3}, std::size_t{8}, std::size_t{21}}) {
    std::array<float, 21> buffer{};
    buffer.fill(0.25F);
    buffer[1] = kNan;
    buffer[count - 2] = -kInf;
    buffer[count - 1] = -2.5F;
    if (count > 8) buffer[5] = 3.0F;
    const std::vector<float> samples(buffer.begin(), buffer.begin() + static_cast<long>(count));
    double peak = 0.0;
    double sum_squares = 0.0;
    std::size_t finite = 0;
    for (const float sample : samples) {
      if (!std::isfinite(sample)) continue;
      peak = std::max(peak, static_cast<double>(std::fabs(sample)));
      sum_squares += static_cast<double>(sample) * sample;
      ++finite;
    }
    SourceCounters counters;
    measure_levels(samples.data(), samples.size(), counters);
    EXPECT_NEAR(counters.peak_level_dbfs, 20.0 * std::log10(peak), 1e-9) << count;
    EXPECT_NEAR(counters.rms_level_dbfs,
                20.0 * std::log10(std::sqrt(sum_squares / static_cast<double>(finite))), 1e-9)
        << count;
  }
  SourceCounters counters;
  const std::vector<float> none(9, kNan);
  measure_levels(none.data(), none.size(), counters);
  EXPECT_EQ(counters.peak_level_dbfs, kLevelFloorDbfs);
  EXPECT_EQ(counters.rms_level_dbfs, kLevelFloorDbfs);
}

TEST_F(RecordingSourceTest, SilenceReportsTheLevelFloor) {
  write_file(path("silence.wav"), SF_FORMAT_WAV | SF_FORMAT_PCM_16, 1,
             std::vector<float>(256, 0.0F));
  RecordingSource source(path("silence.wav"), {}, 256);
  doa::AudioBlockView block;
  ASSERT_TRUE(source.next(block));
  EXPECT_EQ(source.counters().peak_level_dbfs, -120.0);
  EXPECT_EQ(source.counters().rms_level_dbfs, -120.0);
}

TEST_F(RecordingSourceTest, TruncatedWavIsRejectedAtOpen) {
  constexpr int kChannels = 4;
  const fs::path file = path("cut.wav");
  write_file(file, SF_FORMAT_WAV | SF_FORMAT_PCM_16, kChannels, known_interleaved(1000, kChannels));
  // 8 bytes per frame: chop 300 frames and a half off the end.
  fs::resize_file(file, fs::file_size(file) - 300 * 8 - 4);
  EXPECT_EQ(error_of(file, {}, 256),
            file.string() + ": truncated: header declares 1000 frames, data ends at frame 699");
}

// Every container libsndfile would quietly shorten is refused at open, naming the frames the
// header declares and those present; the same files intact open. 4 channels of PCM16 or float:
// 8 or 16 bytes per frame, cut by 300 frames and a bit.
struct ContainerCase {
  const char* name;
  int format;
  int bytes_per_frame;
};

class EachContainer : public RecordingSourceTest,
                      public ::testing::WithParamInterface<ContainerCase> {};

TEST_P(EachContainer, TruncatedFileIsRefusedAtOpenAndIntactFileOpens) {
  const ContainerCase& format = GetParam();
  constexpr int kChannels = 4;
  const fs::path intact = path(std::string("intact.") + format.name);
  write_file(intact, format.format, kChannels, known_interleaved(1000, kChannels));
  EXPECT_EQ(error_of(intact, {}, 256), "(no error)");
  RecordingSource whole(intact, {}, 256);
  EXPECT_EQ(whole.total_frames(), 1000);

  const fs::path cut = path(std::string("cut.") + format.name);
  write_file(cut, format.format, kChannels, known_interleaved(1000, kChannels));
  fs::resize_file(cut, fs::file_size(cut) - 300 * format.bytes_per_frame - 4);
  EXPECT_EQ(error_of(cut, {}, 256),
            cut.string() + ": truncated: header declares 1000 frames, data ends at frame 699");
}

INSTANTIATE_TEST_SUITE_P(
    Containers, EachContainer,
    ::testing::Values(ContainerCase{"wav_float", SF_FORMAT_WAV | SF_FORMAT_FLOAT, 16},
                      ContainerCase{"rf64_pcm16", SF_FORMAT_RF64 | SF_FORMAT_PCM_16, 8},
                      ContainerCase{"rf64_float", SF_FORMAT_RF64 | SF_FORMAT_FLOAT, 16},
                      ContainerCase{"aiff_pcm16", SF_FORMAT_AIFF | SF_FORMAT_PCM_16, 8},
                      ContainerCase{"aifc_float", SF_FORMAT_AIFF | SF_FORMAT_FLOAT, 16},
                      ContainerCase{"w64_pcm16", SF_FORMAT_W64 | SF_FORMAT_PCM_16, 8},
                      ContainerCase{"au_pcm16", SF_FORMAT_AU | SF_FORMAT_PCM_16, 8},
                      ContainerCase{"au_le_float",
                                    SF_FORMAT_AU | SF_FORMAT_FLOAT | SF_ENDIAN_LITTLE, 16}),
    [](const auto& param_info) { return std::string(param_info.param.name); });

// CAF: libsndfile writes chunks after the audio data, so the cut takes them first; the audio
// then ends before the declared 1000 frames all the same.
TEST_F(RecordingSourceTest, TruncatedCafIsRefusedAtOpen) {
  const fs::path cut = path("cut.caf");
  write_file(cut, SF_FORMAT_CAF | SF_FORMAT_PCM_16, 4, known_interleaved(1000, 4));
  EXPECT_EQ(error_of(cut, {}, 256), "(no error)");
  fs::resize_file(cut, fs::file_size(cut) - 300 * 8 - 4);
  EXPECT_NE(error_of(cut, {}, 256).find(cut.string() + ": truncated: header declares 1000 frames"),
            std::string::npos)
      << error_of(cut, {}, 256);
}

TEST_F(RecordingSourceTest, TruncatedFlacDeliversWhatIsThereThenEnds) {
  constexpr int kChannels = 2;
  constexpr std::int64_t kFrames = 48000;
  const fs::path file = path("cut.flac");
  write_file(file, SF_FORMAT_FLAC | SF_FORMAT_PCM_16, kChannels,
             known_interleaved(kFrames, kChannels));
  fs::resize_file(file, fs::file_size(file) / 2);

  RecordingSource source(file, {}, 1024);
  EXPECT_EQ(source.total_frames(), kFrames);  // STREAMINFO still declares the whole length
  doa::AudioBlockView block;
  std::int64_t delivered = 0;
  double worst_error = 0.0;
  while (source.next(block)) {
    EXPECT_EQ(block.first_sample, delivered);
    for (std::size_t frame = 0; frame < block.frames; ++frame) {
      for (int channel = 0; channel < kChannels; ++channel) {
        worst_error = std::max(
            worst_error,
            static_cast<double>(std::fabs(
                block.sample(frame, channel) -
                known_signal(block.first_sample + static_cast<std::int64_t>(frame), channel))));
      }
    }
    delivered += static_cast<std::int64_t>(block.frames);
  }
  EXPECT_TRUE(source.truncated());
  EXPECT_GT(delivered, 0);
  EXPECT_LT(delivered, kFrames);
  EXPECT_EQ(source.frames_delivered(), delivered);
  EXPECT_LE(worst_error, kPcm16Tolerance) << "the frames before the cut are intact";
  EXPECT_FALSE(source.next(block));
}

TEST_F(RecordingSourceTest, MissingFile) {
  const fs::path file = path("nowhere.wav");
  EXPECT_EQ(error_of(file, {}, 256), file.string() + ": recording not found");
}

TEST_F(RecordingSourceTest, DirectoryIsNotARecording) {
  EXPECT_EQ(error_of(directory_, {}, 256),
            directory_.string() + ": is a directory, not a recording");
}

TEST_F(RecordingSourceTest, NotAudio) {
  const fs::path file = path("notes.wav");
  std::ofstream(file) << "these are field notes, not a recording\n";
  const std::string error = error_of(file, {}, 256);
  EXPECT_EQ(error.rfind(file.string() + ": cannot read as audio (", 0), 0U) << error;
}

TEST_F(RecordingSourceTest, ZeroByteFileIsNotAudio) {
  const fs::path file = path("empty.wav");
  std::ofstream{file};
  const std::string error = error_of(file, {}, 256);
  EXPECT_EQ(error.rfind(file.string() + ": cannot read as audio (", 0), 0U) << error;
}

TEST_F(RecordingSourceTest, ZeroFramesIsAnError) {
  const fs::path file = path("header_only.wav");
  write_file(file, SF_FORMAT_WAV | SF_FORMAT_PCM_16, 2, {});
  EXPECT_EQ(error_of(file, {}, 256), file.string() + ": empty recording (0 frames)");
}

TEST_F(RecordingSourceTest, ChannelMapBeyondTheFileIsAnError) {
  const fs::path file = path("two.wav");
  write_file(file, SF_FORMAT_WAV | SF_FORMAT_PCM_16, 2, known_interleaved(10, 2));
  EXPECT_EQ(error_of(file, {1, 0, 2}, 256),
            file.string() + ": channel_map[2] = 2 but the recording has 2 channels (0..1)");
  EXPECT_EQ(error_of(file, {-1, 0}, 256),
            file.string() + ": channel_map[0] = -1 but the recording has 2 channels (0..1)");
}

TEST_F(RecordingSourceTest, ZeroBlockSizeIsAnError) {
  const fs::path file = path("two.wav");
  write_file(file, SF_FORMAT_WAV | SF_FORMAT_PCM_16, 2, known_interleaved(10, 2));
  EXPECT_EQ(error_of(file, {}, 0), file.string() + ": block size must be at least 1 frame");
}

}  // namespace
}  // namespace dronetrack::capture
