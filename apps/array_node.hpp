#pragma once
// One array node as a process runs it: an audio source feeding a NodePipeline, plus the
// once-a-second health report. Used by `replay` (all nodes in one process) and `node` (DDS).
// It logs each audio health problem the pipeline raises as one warning line
// (docs/deployment.md "Audio health").
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "capture/audio_source.hpp"
#include "capture/recording_source.hpp"
#include "config/site_config.hpp"
#include "doa/node_pipeline.hpp"
#include "doa/node_status.hpp"

namespace dronetrack::apps {

// Sees every block of raw audio a node reads, on the node's thread (incident capture).
class AudioTap {
 public:
  virtual ~AudioTap() = default;
  virtual void on_audio(int array_index, const doa::AudioBlockView& block) = 0;
};

class ArrayNode {
 public:
  // A moving array's DOAs are stamped with its pose file's pose at their time unless
  // `pose_from_file` is false (the live node, which stamps them from the ArrayPose stream).
  // `start_sample`: the stream sample index of the source's first sample (a recording that
  // started after the site's earliest, lined up by its recorded start time; 0 otherwise).
  ArrayNode(const config::SiteConfig& site, int array_index,
            std::unique_ptr<capture::AudioSource> source, bool pose_from_file = true,
            std::int64_t start_sample = 0);
  // Every block read from now on also goes to `tap` (not owned; nullptr: none).
  void set_audio_tap(AudioTap* tap) { tap_ = tap; }

  // Reads one block and appends the DOAs it completes. False at end of stream. Logs a warning
  // for every audio health problem raised (also on the last stretch, at the end).
  bool step(std::vector<doa::DoaMeasurement>& doas);
  // Stream time at the end of the last block read, seconds since sample 0.
  double time_s() const { return static_cast<double>(samples_read_) / sample_rate_hz_; }
  // No DOA older than this will come from this node any more (see NodePipeline).
  double settled_time_s() const { return time_s() - pipeline_.output_latency_s(); }
  // True (and fills `status`) when a status report is due: once per second of stream time.
  bool status_due(doa::NodeStatus& status);
  doa::NodeStatus status() const;
  const std::string& array_id() const { return array_id_; }
  int array_index() const { return array_index_; }
  double sample_rate_hz() const { return sample_rate_hz_; }
  const capture::AudioSource& source() const { return *source_; }
  std::int64_t frames_processed() const { return pipeline_.diagnostics().frames_processed; }
  const doa::NodeDiagnostics& diagnostics() const { return pipeline_.diagnostics(); }
  // DOAs dropped for want of a pose at their time (pose file).
  std::int64_t unposed_doas() const { return pipeline_.diagnostics().unposed_doas; }

 private:
  void warn_health_problems() const;

  std::string array_id_;
  int array_index_;
  std::vector<int> channel_map_;  // input channel of each mic (for the warnings)
  std::unique_ptr<capture::AudioSource> source_;
  doa::NodePipeline pipeline_;
  double sample_rate_hz_;
  std::int64_t start_sample_ = 0;
  std::int64_t samples_read_ = 0;
  AudioTap* tap_ = nullptr;
  double next_status_s_ = 0.0;
  bool finished_ = false;
  std::int64_t silent_stretches_ = 0;  // blocks of digital silence on every channel, per run
  bool in_silence_ = false;
};

// The warning line for one audio health problem of `array_id`'s channel (mic) `event.channel`,
// e.g. "A2 channel 3: all samples non-finite (NaN/inf) since 0.00 s; ...". `input_channel` is
// the recording's or device's channel the mic is on (named when it differs).
std::string health_warning(const std::string& array_id, int input_channel,
                           const doa::HealthEvent& event);
// The warning line for one problem ArrayHealth raised on a channel, naming the array and the
// channel, e.g. "A1 channel 2: polarity flipped: its pairs correlate negative on 100 % of the
// frames with a source at 1.02 s; rewire the mic or invert the channel". A swap names the other
// channel too, on its input channel `other_input_channel`.
std::string array_health_warning(const std::string& array_id, int input_channel,
                                 const doa::ArrayHealthEvent& event, int other_input_channel = -1);
// One line summing up a node's audio problems over the whole run ("" when it had none), e.g.
// "A2 channel 3: non-finite 100 % of samples; channel 0: clipped 2.1 % of samples".
std::string health_summary(const doa::NodeStatus& status);

// "" when the array is fixed or its pose file covers every analysis frame of `recording` (up to
// max_duration_s when > 0); otherwise one line naming the pose file and the first frame time
// it does not cover. Replay and node check this before anything is written.
std::string pose_span_problem(const config::SiteConfig& site, std::size_t array_index,
                              const std::filesystem::path& recording, double max_duration_s = 0.0);

// Opens the array's recording (its channel map applied) in blocks of about block_s seconds.
std::unique_ptr<capture::RecordingSource> open_recording(const config::ArrayConfig& array,
                                                         const std::filesystem::path& recording,
                                                         double block_s);

}  // namespace dronetrack::apps
