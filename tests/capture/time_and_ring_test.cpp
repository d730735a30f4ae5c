// Issue 19's capture parts: the time sidecar (round trip, the BWF bext time reference, every
// error), the on-disk audio ring (wrap-around, gaps, what it no longer holds, a write error on a
// full file system) and the WAV writer.
#include <sndfile.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "capture/audio_file_writer.hpp"
#include "capture/disk_audio_ring.hpp"
#include "capture/recording_source.hpp"
#include "capture/recording_time.hpp"

namespace dronetrack::capture {
namespace {

namespace fs = std::filesystem;

class CaptureFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    directory_ = fs::temp_directory_path() /
                 ("dronetrack_time_ring_" + std::to_string(::getpid()) + "_" +
                  ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(directory_);
  }
  void TearDown() override { fs::remove_all(directory_); }
  // The sidecar of `recording` read back, or the one-line error it gives.
  std::string error_of(const std::string& sidecar_text) {
    const fs::path recording = directory_ / "x.wav";
    std::ofstream(time_sidecar_path(recording)) << sidecar_text;
    try {
      read_recording_time(recording);
    } catch (const std::runtime_error& error) {
      return error.what();
    }
    return "(no error)";
  }
  fs::path directory_;
};

TEST(RecordingTime, FormatsAndParsesUtcWithMicroseconds) {
  // 2026-11-26T04:00:00.5Z, by date arithmetic: 20783 days after 1970-01-01, plus 4 h.
  const std::int64_t ns = (20783LL * 86400 + 4 * 3600) * 1'000'000'000LL + 500'000'000LL;
  EXPECT_EQ(format_utc(ns), "2026-11-26T04:00:00.500000Z");
  EXPECT_EQ(parse_utc("2026-11-26T04:00:00.5Z"), ns);
  EXPECT_EQ(parse_utc("2026-11-26T04:00:00.500000000Z"), ns);
  EXPECT_EQ(parse_utc("2026-11-26T04:00:00Z"), ns - 500'000'000LL);
  EXPECT_EQ(format_utc(-1), "1969-12-31T23:59:59.999999Z");
  EXPECT_FALSE(parse_utc("2026-11-26 04:00:00Z"));
  EXPECT_FALSE(parse_utc("2026-11-26T04:00:00.5"));
  EXPECT_FALSE(parse_utc("2026-13-26T04:00:00Z"));
  EXPECT_FALSE(parse_utc("2026-11-26T04:00:00.1234567890Z"));
  // bext: 4 h and 0.5 s after midnight at 48 kHz.
  EXPECT_EQ(samples_since_midnight(ns, 48000.0), (4u * 3600u * 48000u) + 24000u);
}

TEST_F(CaptureFiles, WavWithSidecarAndBextRoundTrip) {
  RecordingTime time;
  time.array_id = "N2";
  time.utc_start_unix_ns = (20783LL * 86400 + 4 * 3600) * 1'000'000'000LL + 250'000'000LL;
  time.sample_rate_hz = 16000.0;
  time.first_sample = 123456;
  time.channels = 3;
  time.channel_order = "mic";
  time.software_version = "9.9.9";
  const fs::path file = directory_ / "N2.wav";
  std::vector<float> samples(3 * 1000);
  for (std::size_t i = 0; i < samples.size(); ++i)
    samples[i] = 0.001F * static_cast<float>(i % 997);
  {
    AudioFileWriter writer(file, time);
    writer.write(samples.data(), 600);
    writer.write(samples.data() + 3 * 600, 400);
    EXPECT_FALSE(fs::exists(file)) << "in place only at commit";
    writer.commit();
  }
  const std::optional<RecordingTime> read = read_recording_time(file);
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->array_id, "N2");
  EXPECT_EQ(read->utc_start_unix_ns, time.utc_start_unix_ns);
  EXPECT_EQ(read->sample_rate_hz, 16000.0);
  EXPECT_EQ(read->first_sample, 123456);
  EXPECT_EQ(read->channels, 3);
  EXPECT_EQ(read->channel_order, "mic");
  EXPECT_EQ(read->software_version, "9.9.9");

  SF_INFO info{};
  SNDFILE* handle = sf_open(file.c_str(), SFM_READ, &info);
  ASSERT_NE(handle, nullptr);
  SF_BROADCAST_INFO bext{};
  ASSERT_EQ(sf_command(handle, SFC_GET_BROADCAST_INFO, &bext, sizeof bext), SF_TRUE);
  const std::uint64_t reference =
      (static_cast<std::uint64_t>(bext.time_reference_high) << 32) | bext.time_reference_low;
  EXPECT_EQ(reference, 4u * 3600u * 16000u + 4000u);
  EXPECT_EQ(std::string(bext.origination_date, 10), "2026-11-26");
  EXPECT_EQ(std::string(bext.origination_time, 8), "04:00:00");
  sf_close(handle);

  RecordingSource source(file, {}, 1000);
  doa::AudioBlockView block;
  ASSERT_TRUE(source.next(block));
  ASSERT_EQ(block.frames, 1000U);
  for (std::size_t i = 0; i < samples.size(); i += 101) EXPECT_EQ(block.interleaved[i], samples[i]);
  EXPECT_FALSE(read_recording_time(directory_ / "no-sidecar.wav").has_value());
}

TEST_F(CaptureFiles, SidecarErrorsNameTheFileAndTheKey) {
  const std::string good_start =
      R"({"array": "A1", "utc_start": "2026-11-26T04:00:00.500000Z", )"
      R"("utc_start_unix_ns": 1795665600500000000, "sample_rate_hz": 48000, )";
  const std::string sidecar = (directory_ / "x.wav.json").string();
  EXPECT_EQ(error_of(good_start + R"("first_sample": 0, "channels": 4})"), "(no error)");
  EXPECT_EQ(error_of("{"), sidecar + ": not JSON (" +
                               "[json.exception.parse_error.101] parse error at line 1, column 2: "
                               "syntax error while parsing object key - unexpected end of input; "
                               "expected string literal)");
  EXPECT_EQ(error_of(good_start + R"("channels": 4})"), sidecar + ": first_sample: missing");
  EXPECT_EQ(error_of(good_start + R"("first_sample": -1, "channels": 4})"),
            sidecar + ": first_sample: expected an integer >= 0");
  EXPECT_EQ(error_of(good_start + R"("first_sample": 0, "channels": 0})"),
            sidecar + ": channels: expected an integer from 1 to 1024");
  EXPECT_EQ(error_of(R"({"array": "A1", "utc_start": "2026-11-26T04:00:01.500000Z", )"
                     R"("utc_start_unix_ns": 1795665600500000000, "sample_rate_hz": 48000, )"
                     R"("first_sample": 0, "channels": 4})"),
            sidecar + ": utc_start 2026-11-26T04:00:01.500000Z and utc_start_unix_ns " +
                "1795665600500000000 (2026-11-26T04:00:00.500000Z) disagree");
  EXPECT_EQ(error_of(R"({"array": "A1", "utc_start": "yesterday", )"
                     R"("utc_start_unix_ns": 1795665600500000000, "sample_rate_hz": 48000, )"
                     R"("first_sample": 0, "channels": 4})"),
            sidecar + ": utc_start: expected UTC as 2026-11-26T04:53:27.123456Z");
  EXPECT_EQ(error_of(good_start + R"("first_sample": 0, "channels": 4, "channel_order": "x"})"),
            sidecar + ": channel_order: expected \"input\" or \"mic\"");
}

// A block of `frames` frames of 2 channels whose samples are their own stream index (and
// minus it on channel 1), so any misplaced frame shows.
struct IndexedBlock {
  IndexedBlock(std::int64_t first_sample, std::size_t frames) : samples(2 * frames) {
    for (std::size_t f = 0; f < frames; ++f) {
      samples[2 * f] = static_cast<float>(first_sample + static_cast<std::int64_t>(f));
      samples[2 * f + 1] = -samples[2 * f];
    }
    view.first_sample = first_sample;
    view.frames = frames;
    view.channels = 2;
    view.interleaved = samples.data();
  }
  std::vector<float> samples;
  doa::AudioBlockView view;
};

TEST_F(CaptureFiles, RingHoldsTheLastCapacityFramesAcrossWrapAndGaps) {
  DiskAudioRing ring(directory_ / "ring.f32", 2, 1000);
  EXPECT_EQ(fs::file_size(directory_ / "ring.f32"), 1000U * 2 * sizeof(float));
  for (std::int64_t at = 0; at < 2500; at += 300) ring.append(IndexedBlock(at, 300).view);
  EXPECT_EQ(ring.end_sample(), 2700);
  EXPECT_EQ(ring.oldest_sample(), 1700);
  EXPECT_EQ(fs::file_size(directory_ / "ring.f32"), 1000U * 2 * sizeof(float)) << "bounded";
  std::vector<float> out(2 * 1000);
  ASSERT_TRUE(ring.read(1700, 1000, out.data()));  // wraps at slot 1000
  for (std::size_t f = 0; f < 1000; ++f) {
    ASSERT_EQ(out[2 * f], static_cast<float>(1700 + f));
    ASSERT_EQ(out[2 * f + 1], -static_cast<float>(1700 + f));
  }
  EXPECT_FALSE(ring.read(1699, 10, out.data())) << "overwritten";
  EXPECT_FALSE(ring.read(2650, 100, out.data())) << "not yet written";
  // A gap (a live overrun): nothing before it is offered, the stale slots least of all.
  ring.append(IndexedBlock(3000, 100).view);
  EXPECT_EQ(ring.oldest_sample(), 3000);
  EXPECT_FALSE(ring.read(2600, 10, out.data()));
  ASSERT_TRUE(ring.read(3000, 100, out.data()));
  EXPECT_EQ(out[2 * 99], 3099.0F);
  EXPECT_EQ(ring.write_errors(), 0);
}

TEST_F(CaptureFiles, RingCountsWriteErrorsAndGoesOn) {
  // /dev/full takes the file's place: every write fails with ENOSPC, as on a full disk.
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full on this system";
  fs::create_symlink("/dev/full", directory_ / "full");
  DiskAudioRing full(directory_ / "full", 2, 1000);
  full.append(IndexedBlock(0, 100).view);
  full.append(IndexedBlock(100, 100).view);
  EXPECT_EQ(full.write_errors(), 2);
  EXPECT_EQ(full.last_errno(), ENOSPC);
  std::vector<float> out(200);
  EXPECT_FALSE(full.read(0, 100, out.data())) << "lost frames are never offered";
  EXPECT_EQ(full.end_sample(), 200);
}

}  // namespace
}  // namespace dronetrack::capture
