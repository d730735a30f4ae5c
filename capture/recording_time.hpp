#pragma once
// The wall-clock time of a recording: a sidecar JSON next to the audio file (FILE.wav ->
// FILE.wav.json), written by `record` and by the incident clips, read by `replay` to line arrays
// up (docs/deployment.md "Incident recordings"). WAV files also carry the start in their BWF
// `bext` chunk (time_reference, samples since UTC midnight) for tools that read that; the
// sidecar is what dronetrack reads, because bext cannot hold the date or the array.
//
//   {"array": "A1", "utc_start": "2026-11-26T04:53:27.123456Z",
//    "utc_start_unix_ns": 1795668807123456000, "sample_rate_hz": 48000,
//    "first_sample": 2400000, "channels": 4, "channel_order": "mic",
//    "clock": "system", "software_version": "0.9.0"}
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace dronetrack::capture {

struct RecordingTime {
  std::string array_id;
  std::int64_t utc_start_unix_ns = 0;  // wall-clock time of the file's first sample
  double sample_rate_hz = 0.0;
  // The node's sample-clock index of the file's first sample (0 for a whole stream; a clip's
  // offset into the stream it was cut from).
  std::int64_t first_sample = 0;
  int channels = 0;
  // "input": the device's or recording's channels as they came; "mic": one channel per mic in
  // mic order, the array's channel_map already applied (incident clips).
  std::string channel_order = "input";
  // Where utc_start came from: "system" (the recording host's clock), or "replay" (a clip cut
  // from recordings without time: the replay's own start, common to all its arrays).
  std::string clock = "system";
  std::string software_version;
};

// FILE + ".json".
std::filesystem::path time_sidecar_path(const std::filesystem::path& recording);

// The sidecar of `recording`, or nullopt when it has none. Throws std::runtime_error with one
// line "<sidecar>: <what is wrong>" for a sidecar that is not valid (bad JSON, a missing or
// out-of-range key, utc_start and utc_start_unix_ns that disagree).
std::optional<RecordingTime> read_recording_time(const std::filesystem::path& recording);

// Writes the sidecar of `recording` atomically (common/output_file.hpp). Throws OutputError.
void write_recording_time(const std::filesystem::path& recording, const RecordingTime& time);

// "2026-11-26T04:53:27.123456Z" (microseconds, UTC).
std::string format_utc(std::int64_t unix_ns);
// Parses format_utc's form (fraction of 0-9 digits, trailing Z); nullopt if it is not that.
std::optional<std::int64_t> parse_utc(const std::string& text);

// BWF bext time_reference: samples since UTC midnight of the first sample.
std::uint64_t samples_since_midnight(std::int64_t unix_ns, double sample_rate_hz);

}  // namespace dronetrack::capture
