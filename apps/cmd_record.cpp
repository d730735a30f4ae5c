// `dronetrack record --array ID [--device N] --out FILE [--duration-s S]`: an audio device's
// input to a WAV file (float32) with its wall-clock start beside it (FILE.json and the BWF
// `bext` time reference, capture/recording_time.hpp), so `replay` can line up arrays recorded
// separately. `--from-recording FILE` stands in for the device (a test and integration aid).
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/signals.hpp"
#include "capture/audio_file_writer.hpp"
#include "capture/portaudio_source.hpp"
#include "capture/recording_source.hpp"
#include "capture/stream_recorder.hpp"
#include "capture/wrapped_source.hpp"
#include "common/log.hpp"
#include "common/output_file.hpp"

namespace dronetrack::apps {
namespace {

struct RecordArguments {
  std::string array;
  std::optional<int> device;
  std::string out;
  double duration_s = 0.0;
  int channels = 4;
  double sample_rate_hz = 48000.0;
  std::string from_recording;
  double from_s = 0.0;
  bool realtime = false;
  std::string utc_start;
};

std::int64_t now_unix_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// The loopback at the pace a device would deliver it: a block is handed out when its last
// sample would have been captured.
class PacedSource : public capture::WrappedSource {
 public:
  using WrappedSource::WrappedSource;
  bool next(doa::AudioBlockView& block) override {
    if (!inner().next(block)) return false;
    using Duration = std::chrono::steady_clock::duration;
    const auto at = [&](std::int64_t sample) {
      return std::chrono::duration_cast<Duration>(
          std::chrono::duration<double>(static_cast<double>(sample) / sample_rate_hz()));
    };
    if (!started_) {
      started_ = true;
      start_ = std::chrono::steady_clock::now() - at(block.first_sample);
    }
    std::this_thread::sleep_until(start_ +
                                  at(block.first_sample + static_cast<std::int64_t>(block.frames)));
    return true;
  }

 private:
  std::chrono::steady_clock::time_point start_;
  bool started_ = false;
};

int run(const RecordArguments& arguments) {
  const std::atomic<bool>& stop = install_stop_handlers();
  std::vector<NamedPath> inputs;
  if (!arguments.from_recording.empty())
    inputs.push_back({"--from-recording", arguments.from_recording});
  check_output_paths(inputs, {{"--out", arguments.out},
                              {"--out's time sidecar", capture::time_sidecar_path(arguments.out)}});
  std::optional<std::int64_t> given_start_ns;
  if (!arguments.utc_start.empty()) {
    given_start_ns = capture::parse_utc(arguments.utc_start);
    if (!given_start_ns)
      throw ArgumentError("--utc-start: expected UTC as 2026-11-26T04:53:27.123456Z, got " +
                          arguments.utc_start);
  }

  std::unique_ptr<capture::AudioSource> source;
  capture::PortAudioSource* device = nullptr;
  std::unique_ptr<capture::PortAudioSession> session;
  if (!arguments.from_recording.empty()) {
    auto recording = std::make_unique<capture::RecordingSource>(arguments.from_recording,
                                                                std::vector<int>{}, 4800);
    if (arguments.realtime)
      source = std::make_unique<PacedSource>(std::move(recording));
    else
      source = std::move(recording);
  } else {
    session = std::make_unique<capture::PortAudioSession>();
    capture::PortAudioOptions options;
    options.device_index = arguments.device.value_or(-1);
    options.mics = arguments.channels;
    options.sample_rate_hz = arguments.sample_rate_hz;
    options.block_frames = capture::live_block_frames(arguments.sample_rate_hz);
    auto live = std::make_unique<capture::PortAudioSource>(options);
    device = live.get();
    source = std::move(live);
  }
  const double rate_hz = source->sample_rate_hz();

  // The first block, skipping --from-s of a loopback recording.
  doa::AudioBlockView first;
  const auto skip = static_cast<std::int64_t>(std::llround(arguments.from_s * rate_hz));
  for (;;) {
    if (!source->next(first))
      throw UserError(source->describe() + ": no audio" +
                      (skip > 0
                           ? " after --from-s " + config::format_number(arguments.from_s) + " s"
                           : std::string()));
    const std::int64_t end = first.first_sample + static_cast<std::int64_t>(first.frames);
    if (end <= skip) continue;
    const std::int64_t cut = std::max<std::int64_t>(0, skip - first.first_sample);
    first.interleaved += cut * first.channels;
    first.frames -= static_cast<std::size_t>(cut);
    first.first_sample += cut;
    break;
  }
  capture::RecordingTime time;
  time.array_id = arguments.array;
  time.sample_rate_hz = rate_hz;
  time.channels = source->channels();
  time.software_version = DRONETRACK_VERSION;
  time.clock = given_start_ns ? "given (--utc-start)" : "system";
  if (given_start_ns) {
    time.utc_start_unix_ns = *given_start_ns;
  } else if (device) {
    // The device's sample 0 on the system clock, refined by the first callback.
    time.utc_start_unix_ns = std::llround(
        (device->stream_start_unix_s() + static_cast<double>(first.first_sample) / rate_hz) * 1e9);
  } else {
    // Paced, the first block came when its last sample would have been captured.
    const double first_block_s =
        arguments.realtime ? static_cast<double>(first.frames) / rate_hz : 0.0;
    time.utc_start_unix_ns = now_unix_ns() - std::llround(first_block_s * 1e9);
  }
  capture::AudioFileWriter writer(arguments.out, time);
  const auto max_frames = static_cast<std::int64_t>(std::llround(arguments.duration_s * rate_hz));
  const capture::StreamRecording recording =
      capture::record_stream(*source, first, writer, max_frames, &stop);
  writer.commit();
  std::string lost;
  if (recording.gap_frames > 0)
    lost =
        "; " + std::to_string(recording.gap_frames) + " frames lost to overruns, written as zeros";
  log::info("record: ", arguments.array, ": ", static_cast<double>(recording.frames) / rate_hz,
            " s (", recording.frames, " frames x ", time.channels, " channels, ", rate_hz,
            " Hz) from ", source->describe(), " to ", arguments.out, ", starting ",
            capture::format_utc(time.utc_start_unix_ns), lost);
  return 0;
}

}  // namespace

void register_record(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<RecordArguments>();
  auto* command = root.add_subcommand(
      "record",
      "Record an audio device to a WAV file with its UTC start time (FILE.json), for replay");
  command->add_option("--array", arguments->array, "Id of the array being recorded")->required();
  auto* device = command->add_option("--device", arguments->device,
                                     "PortAudio input device index (dronetrack devices); default: "
                                     "the default input");
  command->add_option("--out", arguments->out, "The WAV file to write (float32)")->required();
  command
      ->add_option("--duration-s", arguments->duration_s,
                   "Stop after this many seconds (default: until Ctrl-C or the input ends)")
      ->check(finite_in(0.0, kMaxDuration_s));
  command->add_option("--channels", arguments->channels, "Input channels to record")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  command->add_option("--rate-hz", arguments->sample_rate_hz, "Sample rate")
      ->capture_default_str()
      ->check(finite_in(1000.0, 1e6));
  auto* from = command
                   ->add_option("--from-recording", arguments->from_recording,
                                "Test/integration aid: take the audio from this file instead of "
                                "a device (all its channels, at its rate)")
                   ->check(CLI::ExistingFile)
                   ->excludes(device);
  command
      ->add_option("--from-s", arguments->from_s,
                   "With --from-recording: start this many seconds into the file")
      ->check(finite_in(0.0, kMaxDuration_s))
      ->needs(from);
  command
      ->add_flag("--realtime", arguments->realtime,
                 "With --from-recording: deliver it at the pace a device would (default: as fast "
                 "as it reads)")
      ->needs(from);
  command
      ->add_option("--utc-start", arguments->utc_start,
                   "With --from-recording: stamp the first sample with this UTC time "
                   "(2026-11-26T04:53:27.5Z) instead of the clock's")
      ->needs(from);
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
