#include "capture/audio_file_writer.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include <sndfile.h>

namespace dronetrack::capture {
namespace {

// Copies without the terminating zero where the field is full: bext text fields are fixed-size.
void copy_field(char* field, std::size_t size, const std::string& text) {
  std::memset(field, 0, size);
  std::memcpy(field, text.data(), std::min(size, text.size()));
}

}  // namespace

AudioFileWriter::AudioFileWriter(const std::filesystem::path& file, const RecordingTime& time)
    : file_(file), time_(time), out_(std::make_unique<OutputFile>(file)) {
  SF_INFO info{};
  info.samplerate = static_cast<int>(std::lround(time.sample_rate_hz));
  info.channels = time.channels;
  info.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
  handle_ = sf_open_fd(out_->descriptor(), SFM_WRITE, &info, SF_FALSE);
  if (!handle_) throw OutputError(file.string() + ": cannot write (" + sf_strerror(nullptr) + ")");
  // BWF time reference, for audio tools; set before the first sample is written.
  SF_BROADCAST_INFO bext{};
  copy_field(bext.description, sizeof bext.description, "dronetrack array " + time.array_id);
  copy_field(bext.originator, sizeof bext.originator, "dronetrack " + time.software_version);
  copy_field(bext.originator_reference, sizeof bext.originator_reference, time.array_id);
  const std::string utc = format_utc(time.utc_start_unix_ns);  // 2026-11-26T04:53:27.123456Z
  copy_field(bext.origination_date, sizeof bext.origination_date, utc.substr(0, 10));
  copy_field(bext.origination_time, sizeof bext.origination_time, utc.substr(11, 8));
  const std::uint64_t reference =
      samples_since_midnight(time.utc_start_unix_ns, time.sample_rate_hz);
  bext.time_reference_low = static_cast<std::uint32_t>(reference & 0xffffffffu);
  bext.time_reference_high = static_cast<std::uint32_t>(reference >> 32);
  bext.version = 1;
  sf_command(handle_, SFC_SET_BROADCAST_INFO, &bext, sizeof bext);
}

AudioFileWriter::~AudioFileWriter() {
  if (handle_) sf_close(handle_);
}

void AudioFileWriter::write(const float* interleaved, std::size_t frames) {
  const auto count = static_cast<sf_count_t>(frames);
  if (sf_writef_float(handle_, interleaved, count) != count)
    throw OutputError(file_.string() + ": write failed (" + sf_strerror(handle_) + ")");
  frames_written_ += count;
}

void AudioFileWriter::commit() {
  const std::string error = sf_strerror(handle_);
  const int closed = sf_close(handle_);
  handle_ = nullptr;
  if (closed != 0) throw OutputError(file_.string() + ": close failed (" + error + ")");
  out_->commit();
  write_recording_time(file_, time_);
}

}  // namespace dronetrack::capture
