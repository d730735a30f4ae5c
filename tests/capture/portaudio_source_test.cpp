// PortAudioSource on a real PortAudio stream. Build machines rarely have a sound card, so the
// test gives ALSA one: before PortAudio starts, HOME points at a temporary directory whose
// .asoundrc defines a capture PCM of ALSA's `file` plugin reading a raw float file we wrote
// (over a `null` slave). PortAudio's ALSA host lists it like any device; its callback then
// delivers our known signal, so the channel map, the samples passed unchanged (a NaN
// included), the level meter and the sample timestamps are checked end to end. The `null` slave is
// not paced by a clock, so the callback runs as fast as it can: the ring overruns by design, which
// tests the drop path. Where PortAudio has no ALSA host, or the machine has no default input, tests
// say so and skip.
#include "capture/portaudio_source.hpp"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "capture/devices.hpp"
#include "capture/recording_source.hpp"
#include "capture/stream_recorder.hpp"

namespace dronetrack::capture {
namespace {

namespace fs = std::filesystem;

constexpr const char* kTestDevice = "dronetrack_test_capture";
constexpr int kFileChannels = 4;
constexpr std::int64_t kFileFrames = 64 * 256;
constexpr std::int64_t kNanFrame = 20;
constexpr std::int64_t kClipFrame = 10;

// Channel c of frame n; distinct per channel and per frame so a swap or a shift is visible.
float file_signal(std::int64_t frame, int channel) {
  if (frame == kNanFrame && channel == 1) return std::numeric_limits<float>::quiet_NaN();
  if (frame == kClipFrame && channel == 3) return 1.0F;
  return static_cast<float>(0.5 * static_cast<double>(frame % 1000) / 1000.0 + 0.1 * channel - 0.2);
}

class AlsaTestDevice : public ::testing::Environment {
 public:
  void SetUp() override {
    directory_ = fs::temp_directory_path() / ("dronetrack_pa_test_" + std::to_string(::getpid()));
    fs::create_directories(directory_);
    const fs::path raw = directory_ / "capture.raw";
    {
      std::ofstream out(raw, std::ios::binary);
      for (std::int64_t frame = 0; frame < kFileFrames; ++frame) {
        for (int channel = 0; channel < kFileChannels; ++channel) {
          const float value = file_signal(frame, channel);
          out.write(reinterpret_cast<const char*>(&value), sizeof value);
        }
      }
    }
    std::ofstream(directory_ / ".asoundrc") << "pcm." << kTestDevice << " {\n"
                                            << "  type file\n"
                                            << "  slave.pcm \"null\"\n"
                                            << "  file \"/dev/null\"\n"
                                            << "  infile \"" << raw.string() << "\"\n"
                                            << "  format \"raw\"\n"
                                            << "}\n";
    // ALSA reads ~/.asoundrc when PortAudio first initialises it, i.e. after this.
    ::setenv("HOME", directory_.c_str(), 1);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(directory_, ignored);
  }

 private:
  fs::path directory_;
};

[[maybe_unused]] auto* const alsa_test_device =
    ::testing::AddGlobalTestEnvironment(new AlsaTestDevice);

std::optional<DeviceInfo> find_test_device() {
  for (const DeviceInfo& device : list_input_devices()) {
    if (device.name == kTestDevice) return device;
  }
  return std::nullopt;
}

std::string error_of(const PortAudioOptions& options) {
  try {
    PortAudioSource source(options);
  } catch (const std::runtime_error& error) {
    return error.what();
  }
  return "(no error)";
}

TEST(Devices, ListingGivesPlausibleInputDevices) {
  const std::vector<DeviceInfo> devices = list_input_devices();
  int defaults = 0;
  for (const DeviceInfo& device : devices) {
    EXPECT_GE(device.index, 0);
    EXPECT_FALSE(device.name.empty());
    EXPECT_FALSE(device.host_api.empty());
    EXPECT_GT(device.max_input_channels, 0) << device.name;
    EXPECT_GT(device.default_sample_rate_hz, 0.0) << device.name;
    defaults += device.is_default_input ? 1 : 0;
  }
  EXPECT_LE(defaults, 1);
  std::cout << devices.size() << " input device(s) visible to PortAudio\n";
}

class TestCapture : public ::testing::Test {
 protected:
  void SetUp() override {
    device_ = find_test_device();
    if (!device_) {
      GTEST_SKIP() << "PortAudio does not list the ALSA test PCM '" << kTestDevice
                   << "' (no ALSA host API in this PortAudio?): no capture stream to test";
    }
  }
  PortAudioOptions options() const {
    PortAudioOptions options;
    options.device_index = device_->index;
    options.sample_rate_hz = 16000.0;
    options.block_frames = 256;
    options.ring_blocks = 16;
    return options;
  }
  std::optional<DeviceInfo> device_;
};

TEST_F(TestCapture, DeliversTheDeviceSignalThroughTheChannelMapWithSampleTimestamps) {
  PortAudioOptions settings = options();
  settings.channel_map = {3, 1};  // mic 0 on input 3, mic 1 on input 1
  const double before_unix_s =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  PortAudioSource source(settings);
  EXPECT_EQ(source.channels(), 2);
  EXPECT_EQ(source.device_channels(), 4) << "opens enough inputs for the highest mapped one";
  EXPECT_EQ(source.sample_rate_hz(), 16000.0);
  // The unpaced device fills the ring long before we read: the first drops happen here.
  std::this_thread::sleep_for(std::chrono::milliseconds(30));

  doa::AudioBlockView block;
  std::int64_t delivered = 0;
  std::int64_t previous_first = -1;
  std::int64_t blocks_checked_against_file = 0;
  while (delivered < 40 && source.next(block)) {
    EXPECT_EQ(block.channels, 2);
    EXPECT_EQ(block.frames, 256U);
    EXPECT_GT(block.first_sample, previous_first);
    EXPECT_EQ(block.first_sample % 256, 0);
    if (delivered < 16) {
      // The ring held blocks 0..15 before the first drop: no gap among them.
      EXPECT_EQ(block.first_sample, delivered * 256);
    }
    // Every missing block before this one was counted as an overrun by the time we got it.
    EXPECT_GE(source.counters().overruns, block.first_sample / 256 - delivered);
    if (block.first_sample + 256 <= kFileFrames) {
      for (std::size_t frame = 0; frame < block.frames; ++frame) {
        const std::int64_t index = block.first_sample + static_cast<std::int64_t>(frame);
        ASSERT_EQ(block.sample(frame, 0), file_signal(index, 3)) << "frame " << index;
        if (index == kNanFrame) {
          ASSERT_TRUE(std::isnan(block.sample(frame, 1))) << "passed on for the node to count";
        } else {
          ASSERT_EQ(block.sample(frame, 1), file_signal(index, 1)) << "frame " << index;
        }
      }
      ++blocks_checked_against_file;
    }
    if (delivered == 0) {
      EXPECT_NEAR(source.counters().peak_level_dbfs, 0.0, 1e-9);
    }
    previous_first = block.first_sample;
    ++delivered;
  }
  EXPECT_EQ(delivered, 40);
  EXPECT_GE(blocks_checked_against_file, 16);
  EXPECT_GT(source.counters().overruns, 0) << "an unpaced device must overrun a 16-block ring";
  EXPECT_GT(previous_first, 39 * 256) << "the blocks after the drops start later";
  EXPECT_GE(source.stream_start_unix_s(), before_unix_s - 1.0);
  EXPECT_LE(source.stream_start_unix_s(), before_unix_s + 5.0);
}

// `dronetrack record`'s path (issue 19) on the test PCM: the unpaced device overruns, and the
// recorded file still holds sample k of the stream at frame k (the lost blocks as zeros), with
// the stream's start time beside it.
TEST_F(TestCapture, RecordsTheStreamWithItsStartTimeAndZerosForLostBlocks) {
  PortAudioOptions settings = options();
  settings.mics = 4;
  PortAudioSource source(settings);
  std::this_thread::sleep_for(std::chrono::milliseconds(30));  // let the ring overflow
  doa::AudioBlockView first;
  ASSERT_TRUE(source.next(first));
  const fs::path file =
      fs::temp_directory_path() / ("dronetrack_record_" + std::to_string(::getpid()) + ".wav");
  RecordingTime time;
  time.array_id = "A1";
  time.sample_rate_hz = 16000.0;
  time.channels = 4;
  time.utc_start_unix_ns = std::llround(source.stream_start_unix_s() * 1e9);
  StreamRecording recording;
  {
    AudioFileWriter writer(file, time);
    recording = record_stream(source, first, writer, 64 * 256, nullptr);
    writer.commit();
  }
  EXPECT_EQ(recording.frames, 64 * 256);
  EXPECT_GT(recording.gap_frames, 0) << "the unpaced device overruns: zeros fill the gaps";
  EXPECT_EQ(recording.gap_frames % 256, 0);
  const std::optional<RecordingTime> read = read_recording_time(file);
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->utc_start_unix_ns, time.utc_start_unix_ns);
  RecordingSource back(file, {}, 256);
  doa::AudioBlockView block;
  std::int64_t from_file = 0;
  std::int64_t zero_blocks = 0;
  while (back.next(block)) {
    const bool zeros = block.sample(0, 0) == 0.0F && block.sample(255, 3) == 0.0F;
    if (zeros) {
      ++zero_blocks;
      continue;
    }
    // A block that was captured holds the device's samples at its own stream index.
    for (std::size_t frame = 0; frame < block.frames; frame += 37) {
      const std::int64_t index = block.first_sample + static_cast<std::int64_t>(frame);
      if (index >= kFileFrames || index == kNanFrame) continue;
      ASSERT_EQ(block.sample(frame, 2), file_signal(index, 2)) << "frame " << index;
    }
    ++from_file;
  }
  EXPECT_EQ(zero_blocks * 256, recording.gap_frames);
  EXPECT_GE(from_file, 16);
  fs::remove(file);
  fs::remove(time_sidecar_path(file));
}

TEST_F(TestCapture, IdentityMapOverTheArrayMics) {
  PortAudioOptions settings = options();
  settings.mics = 3;
  PortAudioSource source(settings);
  EXPECT_EQ(source.channels(), 3);
  EXPECT_EQ(source.device_channels(), 3);
  doa::AudioBlockView block;
  ASSERT_TRUE(source.next(block));
  EXPECT_EQ(block.first_sample, 0);
  // With three inputs opened the file's floats are read three per frame.
  EXPECT_EQ(block.sample(0, 0), file_signal(0, 0));
  EXPECT_EQ(block.sample(0, 2), file_signal(0, 2));
  EXPECT_EQ(block.sample(1, 0), file_signal(0, 3));
}

TEST_F(TestCapture, StopRequestEndsTheStream) {
  PortAudioOptions settings = options();
  settings.mics = 2;
  PortAudioSource source(settings);
  doa::AudioBlockView block;
  ASSERT_TRUE(source.next(block));
  source.request_stop();
  EXPECT_FALSE(source.next(block));
  EXPECT_FALSE(source.next(block));
}

TEST_F(TestCapture, DeviceWithTooFewChannelsIsAClearError) {
  PortAudioOptions settings = options();
  const int needed = device_->max_input_channels + 1;
  settings.mics = needed;
  EXPECT_EQ(error_of(settings), "device " + std::to_string(device_->index) + " (" + kTestDevice +
                                    ") has " + std::to_string(device_->max_input_channels) +
                                    " input channels, the array needs " + std::to_string(needed));
  // A channel map that reaches past the device's inputs is the same error.
  settings.mics = 0;
  settings.channel_map = {0, device_->max_input_channels};
  EXPECT_EQ(error_of(settings), "device " + std::to_string(device_->index) + " (" + kTestDevice +
                                    ") has " + std::to_string(device_->max_input_channels) +
                                    " input channels, the array needs " + std::to_string(needed));
}

TEST(PortAudioErrors, NonexistentDevice) {
  PortAudioOptions settings;
  settings.device_index = 100000;
  settings.mics = 2;
  const std::string error = error_of(settings);
  EXPECT_EQ(error.rfind("device 100000 does not exist (there are ", 0), 0U) << error;
  EXPECT_NE(error.find(" devices; see `dronetrack devices`)"), std::string::npos) << error;
}

TEST(PortAudioErrors, BadOptions) {
  PortAudioOptions settings;
  settings.mics = 0;
  EXPECT_EQ(error_of(settings), "PortAudio input: the array needs at least 1 mic");
  settings.channel_map = {0, 1, 2};
  settings.mics = 4;
  EXPECT_EQ(error_of(settings),
            "PortAudio input: channel_map has 3 entries but the array has 4 mics");
  settings.channel_map = {0, -2};
  settings.mics = 0;
  EXPECT_EQ(error_of(settings), "PortAudio input: channel_map[1] = -2 is not a channel");
  settings.channel_map = {};
  settings.mics = 2;
  settings.block_frames = 0;
  EXPECT_EQ(error_of(settings), "PortAudio input: block size must be >= 1 frame");
}

// `dronetrack devices` run as a child: it inherits HOME, so it sees the test PCM too.
std::string run_devices_command(const std::string& arguments) {
  const std::string command = std::string(DRONETRACK_BINARY) + " devices " + arguments + " 2>&1";
  std::string output;
  if (FILE* pipe = ::popen(command.c_str(), "r")) {
    char buffer[512];
    while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) output += buffer;
    ::pclose(pipe);
  }
  return output;
}

TEST_F(TestCapture, DevicesCommandListsTheDevice) {
  if (!fs::exists(DRONETRACK_BINARY)) GTEST_SKIP() << DRONETRACK_BINARY << " not built";
  const std::string channels = std::to_string(device_->max_input_channels);
  const std::string json = run_devices_command("--json");
  EXPECT_NE(json.find(std::string("\"name\":\"") + kTestDevice + "\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"max_input_channels\":" + channels), std::string::npos) << json;
  EXPECT_NE(json.find("\"host_api\":\"ALSA\""), std::string::npos) << json;
  const std::string table = run_devices_command("");
  EXPECT_NE(table.find("index"), std::string::npos) << table;
  EXPECT_NE(table.find(kTestDevice), std::string::npos) << table;
  EXPECT_NE(table.find(channels), std::string::npos) << table;
}

TEST(RealDevice, OpensTheDefaultInputWhereThereIsOne) {
  std::optional<DeviceInfo> default_input;
  for (const DeviceInfo& device : list_input_devices()) {
    // With no sound card PortAudio makes the first device, our test PCM, the default.
    if (device.is_default_input && device.name != kTestDevice) default_input = device;
  }
  if (!default_input) {
    GTEST_SKIP() << "this machine has no default audio input device (no sound card): "
                    "only the ALSA test PCM was exercised";
  }
  PortAudioOptions settings;
  settings.device_index = default_input->index;
  settings.mics = 1;
  settings.sample_rate_hz = default_input->default_sample_rate_hz;
  settings.block_frames = 512;
  PortAudioSource source(settings);
  doa::AudioBlockView block;
  ASSERT_TRUE(source.next(block));
  EXPECT_EQ(block.first_sample, 0);
  EXPECT_EQ(block.frames, 512U);
  ASSERT_TRUE(source.next(block));
  EXPECT_GE(block.first_sample, 512);
}

}  // namespace
}  // namespace dronetrack::capture
