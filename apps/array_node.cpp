#include "apps/array_node.hpp"

#include <cmath>
#include <stdexcept>

#include "capture/recording_info.hpp"
#include "capture/recording_source.hpp"

namespace dronetrack::apps {

std::unique_ptr<capture::RecordingSource> open_recording(const config::ArrayConfig& array,
                                                         const std::filesystem::path& recording,
                                                         double block_s) {
  const capture::RecordingInfo info = capture::probe_recording(recording);
  // Before the block buffers are sized from it: a header may claim any rate.
  if (!(info.sample_rate_hz >= config::kMinSampleRate_hz &&
        info.sample_rate_hz <= config::kMaxSampleRate_hz)) {
    throw std::runtime_error(recording.string() + ": sample rate " +
                             std::to_string(info.sample_rate_hz) + " Hz; dronetrack takes 1000 " +
                             "to 1e6 Hz");
  }
  const auto block_frames =
      static_cast<std::size_t>(std::max(1.0, std::round(block_s * info.sample_rate_hz)));
  return std::make_unique<capture::RecordingSource>(recording, array.channel_map, block_frames);
}

ArrayNode::ArrayNode(const config::SiteConfig& site, int array_index,
                     std::unique_ptr<capture::AudioSource> source)
    : array_id_(site.arrays.at(static_cast<std::size_t>(array_index)).geometry.id),
      array_index_(array_index),
      source_(std::move(source)),
      pipeline_(site.arrays.at(static_cast<std::size_t>(array_index)).geometry, array_index,
                site.doa_params(static_cast<std::size_t>(array_index)), source_->sample_rate_hz(),
                site.speed_of_sound_mps),
      sample_rate_hz_(source_->sample_rate_hz()) {
  if (source_->channels() !=
      static_cast<int>(site.arrays[static_cast<std::size_t>(array_index)].geometry.mic_count())) {
    throw std::runtime_error(array_id_ + ": " + source_->describe() + " delivers " +
                             std::to_string(source_->channels()) + " channels for " +
                             std::to_string(pipeline_.geometry().mic_count()) + " mics");
  }
}

bool ArrayNode::step(std::vector<doa::DoaMeasurement>& doas) {
  doa::AudioBlockView block;
  if (!source_->next(block)) return false;
  pipeline_.process(block, doas);
  samples_read_ = block.first_sample + static_cast<std::int64_t>(block.frames);
  return true;
}

doa::NodeStatus ArrayNode::status() const {
  const doa::NodeDiagnostics& diagnostics = pipeline_.diagnostics();
  const capture::SourceCounters& counters = source_->counters();
  doa::NodeStatus status;
  status.array_id = array_id_;
  status.time_s = time_s();
  status.alive = true;
  status.sample_rate_hz = sample_rate_hz_;
  status.overruns = counters.overruns;
  status.clipped_samples = counters.clipped_samples + diagnostics.clipped_samples;
  status.non_finite_samples = counters.non_finite_samples + diagnostics.non_finite_samples;
  status.level_dbfs = diagnostics.level_dbfs;
  status.noise_floor_dbfs = diagnostics.noise_floor_dbfs;
  status.snr_db = diagnostics.snr_db;
  status.detecting = diagnostics.detecting;
  status.software_version = DRONETRACK_VERSION;
  return status;
}

bool ArrayNode::status_due(doa::NodeStatus& status) {
  if (time_s() < next_status_s_) return false;
  next_status_s_ = std::floor(time_s()) + 1.0;
  status = this->status();
  return true;
}

}  // namespace dronetrack::apps
