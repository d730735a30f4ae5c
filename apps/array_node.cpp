#include "apps/array_node.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "capture/recording_info.hpp"
#include "capture/recording_source.hpp"
#include "common/log.hpp"
#include "config/config_reader.hpp"

namespace dronetrack::apps {

namespace {

std::string format(const char* pattern, double value) {
  char text[64];
  std::snprintf(text, sizeof text, pattern, value);
  return text;
}

// "100 %", "2.5 %", "0.013 %".
std::string percent(double share) {
  const double value = 100.0 * share;
  if (value >= 99.95 || value == 0.0) return format("%.0f %%", value);
  return format(value >= 1.0 ? "%.1f %%" : "%.2g %%", value);
}

// "A2 channel 3: ", naming the input channel too when a channel_map moved the mic.
std::string channel_prefix(const std::string& array_id, int input_channel, int mic) {
  std::string line = array_id + " channel " + std::to_string(mic);
  if (input_channel != mic) line += " (input channel " + std::to_string(input_channel) + ")";
  return line + ": ";
}

// The node's DSP settings. A moving array whose pose track the pipeline does not get (the live
// node stamps DOAs from the ArrayPose stream after the pipeline) cannot tell a static source
// from one riding along with the platform: no static look there (docs/doa.md stage 7a).
doa::DoaParams node_params(const config::SiteConfig& site, int array_index, bool pose_from_file) {
  const auto index = static_cast<std::size_t>(array_index);
  doa::DoaParams params = site.doa_params(index);
  const config::ArrayConfig& array = site.arrays.at(index);
  if (array.moving() && !(pose_from_file && !array.pose.empty()))
    params.static_look.enabled = false;
  return params;
}

}  // namespace

std::string health_warning(const std::string& array_id, int input_channel,
                           const doa::HealthEvent& event) {
  std::string line = channel_prefix(array_id, input_channel, event.channel);
  const std::string since = " since " + format("%.2f", event.since_s) + " s";
  const std::string of_stretch = " of " + format("%.2f", event.stretch_s) + " s";
  switch (event.problem) {
    case doa::HealthProblem::non_finite:
      line += event.share >= 1.0
                  ? "all samples non-finite (NaN/inf)"
                  : "non-finite samples (NaN/inf), " + percent(event.share) + of_stretch + ",";
      line += since + "; replaced by 0, frames holding them give no DOA";
      break;
    case doa::HealthProblem::silent:
      line += event.peak == 0.0 ? "silent (all samples 0)"
              : event.rms_dbfs <= -120.0
                  ? "silent (RMS below -120 dBFS)"
                  : "silent (RMS " + format("%.1f", event.rms_dbfs) + " dBFS)";
      line += since + "; no signal from this mic";
      break;
    case doa::HealthProblem::clipped:
      line += "clipping, " + percent(event.share) + of_stretch + " at full scale (|x| >= 0.999)," +
              since + "; frames with more than max_clipped_fraction clipped give no DOA";
      break;
    case doa::HealthProblem::dc_offset:
      line += "DC offset (mean " + format("%+.3f", event.mean) + " of full scale, RMS " +
              format("%.1f", event.rms_dbfs) + " dBFS)" + since;
      break;
    case doa::HealthProblem::absurd_level:
      line += "absurd level (peak " + format("%.3g", event.peak) + " x full scale)" + since +
              "; the recording's scale is wrong (float samples belong in [-1, 1]), frames holding "
              "them give no DOA";
      break;
  }
  return line;
}

std::string array_health_warning(const std::string& array_id, int input_channel,
                                 const doa::ArrayHealthEvent& event, int other_input_channel) {
  std::string line = channel_prefix(array_id, input_channel, event.channel);
  const std::string at = " at " + format("%.2f", event.time_s) + " s";
  switch (event.problem) {
    case doa::ArrayProblem::level_imbalance:
      line += "level " + format("%+.1f", event.level_offset_db) +
              " dB against the array's median in band (after channel_gain_db)" + at +
              "; check the mic and its gain, or calibrate channel_gain_db";
      break;
    case doa::ArrayProblem::dead:
      line += event.share > 0.0 ? "dead: incoherent with every other mic on " +
                                      percent(event.share) + " of the frames with a source"
                                : "dead: level " + format("%+.1f", event.level_offset_db) +
                                      " dB against the array's median in band";
      line += at + "; its pairs give no usable delay";
      break;
    case doa::ArrayProblem::polarity_flipped:
      line += "polarity flipped: its pairs correlate negative on " + percent(event.share) +
              " of the frames with a source" + at + "; rewire the mic or invert the channel";
      break;
    case doa::ArrayProblem::closure:
      line += "TDOA closure fails on the mic triples holding it (array closure residual " +
              format("%.1f", event.closure_residual_us) + " us)" + at +
              "; its pairs pick different peaks: a skewed or moved mic";
      break;
    case doa::ArrayProblem::skew:
      line += "delay " + format("%+.1f", event.delay_offset_us) + " +- " +
              format("%.1f", event.delay_std_us) +
              " us against the array's median channel (fit over " +
              std::to_string(event.delay_sectors) + " direction sectors)" + at +
              "; calibrate channel_delay_s";
      break;
    case doa::ArrayProblem::swapped: {
      std::string other = "channel " + std::to_string(event.other_channel);
      if (other_input_channel != event.other_channel)
        other += " (input channel " + std::to_string(other_input_channel) + ")";
      line += "swapped with " + other + ": the pair delays fit a plane wave with the two " +
              "relabelled (RMS misfit " + format("%.1f", event.swapped_misfit_us) + " us against " +
              format("%.1f", event.wired_misfit_us) + " us as wired)" + at +
              "; swap the two inputs or their channel_map entries";
      break;
    }
  }
  return line;
}

std::string health_summary(const doa::NodeStatus& status) {
  const double samples = std::max(1.0, std::round(status.time_s * status.sample_rate_hz));
  std::string line;
  for (std::size_t c = 0; c < status.channels.size(); ++c) {
    const doa::ChannelStatus& channel = status.channels[c];
    if (channel.problems_seen == 0 && channel.array_problems_seen == 0) continue;
    line += (line.empty() ? status.array_id + " channel " : "; channel ") + std::to_string(c) + ":";
    const char* separator = " ";
    for (int p = 0; p < doa::kHealthProblemCount; ++p) {
      const auto problem = static_cast<doa::HealthProblem>(p);
      if (!doa::has_problem(channel.problems_seen, problem)) continue;
      line += separator;
      separator = ", ";
      switch (problem) {
        case doa::HealthProblem::non_finite:
          line += "non-finite " + std::to_string(channel.non_finite_samples) + " samples (" +
                  percent(static_cast<double>(channel.non_finite_samples) / samples) + ")";
          break;
        case doa::HealthProblem::clipped:
          line += "clipped " + std::to_string(channel.clipped_samples) + " samples (" +
                  percent(static_cast<double>(channel.clipped_samples) / samples) + ")";
          break;
        case doa::HealthProblem::silent:
          line += "silent";
          break;
        case doa::HealthProblem::dc_offset:
          line += "DC offset";
          break;
        case doa::HealthProblem::absurd_level:
          line += "absurd level";
          break;
      }
    }
    for (int p = 0; p < doa::kArrayProblemCount; ++p) {
      const auto problem = static_cast<doa::ArrayProblem>(p);
      if (!doa::has_problem(channel.array_problems_seen, problem)) continue;
      // A silent or all-NaN channel is dead: said already.
      if (problem == doa::ArrayProblem::dead &&
          (doa::has_problem(channel.problems_seen, doa::HealthProblem::silent) ||
           doa::has_problem(channel.problems_seen, doa::HealthProblem::non_finite)))
        continue;
      line += separator;
      separator = ", ";
      std::string name = doa::to_string(problem);
      std::replace(name.begin(), name.end(), '_', ' ');
      line += name;
    }
  }
  return line;
}

std::unique_ptr<capture::RecordingSource> open_recording(const config::ArrayConfig& array,
                                                         const std::filesystem::path& recording,
                                                         double block_s) {
  const capture::RecordingInfo info = capture::probe_recording(recording);
  // Before the block buffers are sized from it: a header may claim any rate.
  if (!(info.sample_rate_hz >= config::kMinSampleRate_hz &&
        info.sample_rate_hz <= config::kMaxSampleRate_hz)) {
    throw std::runtime_error(recording.string() + ": sample rate " +
                             config::format_number(info.sample_rate_hz) + " Hz; dronetrack takes " +
                             config::format_number(config::kMinSampleRate_hz) + " to " +
                             config::format_number(config::kMaxSampleRate_hz) + " Hz");
  }
  const auto block_frames =
      static_cast<std::size_t>(std::max(1.0, std::round(block_s * info.sample_rate_hz)));
  return std::make_unique<capture::RecordingSource>(recording, array.channel_map, block_frames);
}

std::string pose_span_problem(const config::SiteConfig& site, std::size_t array_index,
                              const std::filesystem::path& recording, double max_duration_s) {
  const config::ArrayConfig& array = site.arrays.at(array_index);
  if (array.pose.empty()) return "";
  const capture::RecordingInfo info = capture::probe_recording(recording);
  const double rate_hz = info.sample_rate_hz;
  const doa::DoaParams params = site.doa_params(array_index);
  const auto frame = static_cast<std::int64_t>(std::lround(params.frame_s * rate_hz));
  const auto hop = std::max<std::int64_t>(1, std::lround(params.hop_s * rate_hz));
  std::int64_t samples = info.frames;
  if (max_duration_s > 0.0)
    samples = std::min(samples, static_cast<std::int64_t>(std::ceil(max_duration_s * rate_hz)));
  if (samples < frame) return "";  // no frame, no DOA
  // DOAs carry frame centre times (a smoothed one an earlier frame's): these bound them all.
  const double first_s = 0.5 * static_cast<double>(frame - 1) / rate_hz;
  const double last_s =
      (static_cast<double>((samples - frame) / hop * hop) + 0.5 * static_cast<double>(frame - 1)) /
      rate_hz;
  const double uncovered_s = first_s < array.pose.start_s() ? first_s
                             : last_s > array.pose.end_s()  ? last_s
                                                            : -1.0;
  if (uncovered_s < 0.0) return "";
  return "array " + array.geometry.id + ": " + array.pose_file.string() + " covers t " +
         config::format_number(array.pose.start_s()) + " to " +
         config::format_number(array.pose.end_s()) + " s, but " + recording.string() +
         " has a frame at t " + config::format_number(uncovered_s) +
         " s: no pose then (the pose file must span the recording)";
}

ArrayNode::ArrayNode(const config::SiteConfig& site, int array_index,
                     std::unique_ptr<capture::AudioSource> source, bool pose_from_file,
                     std::int64_t start_sample)
    : array_id_(site.arrays.at(static_cast<std::size_t>(array_index)).geometry.id),
      array_index_(array_index),
      channel_map_(site.arrays[static_cast<std::size_t>(array_index)].channel_map),
      source_(std::move(source)),
      pipeline_(site.arrays.at(static_cast<std::size_t>(array_index)).geometry, array_index,
                node_params(site, array_index, pose_from_file), source_->sample_rate_hz(),
                site.speed_of_sound_mps),
      sample_rate_hz_(source_->sample_rate_hz()),
      start_sample_(start_sample),
      samples_read_(start_sample) {
  if (source_->channels() !=
      static_cast<int>(site.arrays[static_cast<std::size_t>(array_index)].geometry.mic_count())) {
    throw std::runtime_error(array_id_ + ": " + source_->describe() + " delivers " +
                             std::to_string(source_->channels()) + " channels for " +
                             std::to_string(pipeline_.geometry().mic_count()) + " mics");
  }
  const config::ArrayConfig& array = site.arrays[static_cast<std::size_t>(array_index)];
  if (pose_from_file && !array.pose.empty()) pipeline_.set_pose_track(array.pose);
}

bool ArrayNode::step(std::vector<doa::DoaMeasurement>& doas) {
  doa::AudioBlockView block;
  if (!source_->next(block)) {
    if (!finished_) {
      finished_ = true;
      pipeline_.finish();
      warn_health_problems();
    }
    return false;
  }
  block.first_sample += start_sample_;
  if (tap_) tap_->on_audio(array_index_, block);
  // A real microphone never reads exactly 0 on every channel for a whole block: that is a
  // capture gap filled with zeros. One stretch counts once.
  const std::size_t count = block.frames * static_cast<std::size_t>(block.channels);
  const bool silent = count > 0 && std::all_of(block.interleaved, block.interleaved + count,
                                               [](float sample) { return sample == 0.0F; });
  if (silent && !in_silence_) ++silent_stretches_;
  in_silence_ = silent;
  pipeline_.process(block, doas);
  samples_read_ = block.first_sample + static_cast<std::int64_t>(block.frames);
  warn_health_problems();
  return true;
}

void ArrayNode::warn_health_problems() const {
  auto input_of = [&](int channel) {
    const auto mic = static_cast<std::size_t>(channel);
    return mic < channel_map_.size() ? channel_map_[mic] : channel;
  };
  for (const doa::HealthEvent& event : pipeline_.health().events())
    log::warn(health_warning(array_id_, input_of(event.channel), event));
  for (const doa::ArrayHealthEvent& event : pipeline_.array_health().events()) {
    // A silent or all-NaN channel was named for that already: its level says nothing new.
    const doa::HealthFlags audio = pipeline_.health().channel(event.channel).problems_seen;
    if (event.problem == doa::ArrayProblem::dead &&
        (doa::has_problem(audio, doa::HealthProblem::silent) ||
         doa::has_problem(audio, doa::HealthProblem::non_finite)))
      continue;
    log::warn(array_health_warning(array_id_, input_of(event.channel), event,
                                   input_of(event.other_channel)));
  }
}

doa::NodeStatus ArrayNode::status() const {
  const doa::NodeDiagnostics& diagnostics = pipeline_.diagnostics();
  doa::NodeStatus status;
  status.array_id = array_id_;
  status.time_s = time_s();
  status.alive = true;
  status.sample_rate_hz = sample_rate_hz_;
  status.overruns = source_->counters().overruns;
  status.dropouts = silent_stretches_ + diagnostics.stream_gaps;
  status.clipped_samples = diagnostics.clipped_samples;
  status.non_finite_samples = diagnostics.non_finite_samples;
  status.level_dbfs = diagnostics.level_dbfs;
  status.noise_floor_dbfs = diagnostics.noise_floor_dbfs;
  status.snr_db = diagnostics.snr_db;
  status.detecting = diagnostics.detecting;
  status.software_version = DRONETRACK_VERSION;
  const doa::ArrayHealth& array_health = pipeline_.array_health();
  status.closure_residual_us =
      std::min(array_health.closure_residual_us(), doa::kMaxHealthDelay_us);
  status.fit_residual_us = std::min(array_health.fit_residual_us(), doa::kMaxHealthDelay_us);
  for (std::size_t c = 0; c < pipeline_.health().counters().size(); ++c) {
    const doa::ChannelHealthCounters& channel = pipeline_.health().counters()[c];
    const doa::ArrayChannelHealth& compared = array_health.channel_health()[c];
    status.channels.push_back(
        {channel.problems, channel.problems_seen, channel.non_finite_samples,
         channel.clipped_samples, channel.rms_dbfs, compared.problems, compared.problems_seen,
         std::clamp(compared.level_offset_db, -doa::kMaxLevelOffset_db, doa::kMaxLevelOffset_db),
         std::clamp(compared.delay_offset_us, -doa::kMaxHealthDelay_us, doa::kMaxHealthDelay_us),
         std::min(compared.delay_std_us, doa::kMaxHealthDelay_us)});
  }
  return status;
}

bool ArrayNode::status_due(doa::NodeStatus& status) {
  if (time_s() < next_status_s_) return false;
  next_status_s_ = std::floor(time_s()) + 1.0;
  status = this->status();
  return true;
}

}  // namespace dronetrack::apps
