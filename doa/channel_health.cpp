#include "doa/channel_health.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <string>

namespace dronetrack::doa {

namespace {

constexpr double kFloorDbfs = -120.0;
// Raised problems events() can hold between clear_events() calls: a block of up to
// (kEventsPerProblem - 1) x rewarn_s raises each problem of each channel at most kEventsPerProblem
// times. Beyond that (blocks of minutes) the extra events are dropped; the counters and flags still
// hold the problem.
constexpr std::size_t kEventsPerProblem = 4;

double to_dbfs(double amplitude) {
  return amplitude > 0.0 ? std::max(kFloorDbfs, 20.0 * std::log10(amplitude)) : kFloorDbfs;
}

}  // namespace

const char* to_string(HealthProblem problem) {
  switch (problem) {
    case HealthProblem::non_finite:
      return "non_finite";
    case HealthProblem::silent:
      return "silent";
    case HealthProblem::clipped:
      return "clipped";
    case HealthProblem::dc_offset:
      return "dc_offset";
    case HealthProblem::absurd_level:
      return "absurd_level";
  }
  return "unknown";
}

ChannelHealth::ChannelHealth(int channels, double sample_rate_hz,
                             const ChannelHealthSettings& settings)
    : channels_(channels), sample_rate_hz_(sample_rate_hz), settings_(settings) {
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("ChannelHealth: " + what);
  };
  if (channels < 1) fail("channels must be >= 1");
  if (!(sample_rate_hz > 0.0)) fail("sample_rate_hz must be > 0");
  if (!(settings.stretch_s > 0.0)) fail("stretch_s must be > 0");
  if (!(settings.clip_level > 0.0)) fail("clip_level must be > 0");
  if (!(settings.absurd_level >= settings.clip_level)) fail("absurd_level must be >= clip_level");
  if (!(settings.clipped_share >= 0.0 && settings.clipped_share <= 1.0))
    fail("clipped_share must be in [0, 1]");
  if (!(settings.dc_to_rms > 0.0)) fail("dc_to_rms must be > 0");
  if (!std::isfinite(settings.silence_dbfs) || !std::isfinite(settings.dc_dbfs))
    fail("silence_dbfs and dc_dbfs must be finite");
  if (!(settings.rewarn_s >= 0.0)) fail("rewarn_s must be >= 0");
  if (!(settings.min_last_stretch_s >= 0.0)) fail("min_last_stretch_s must be >= 0");
  stretch_frames_ = std::max<std::int64_t>(1, std::llround(settings.stretch_s * sample_rate_hz));
  const auto n = static_cast<std::size_t>(channels);
  stretches_.assign(n, Stretch{});
  counters_.assign(n, ChannelHealthCounters{});
  states_.assign(n, {});
  events_.reserve(n * kHealthProblemCount * kEventsPerProblem);
}

std::int64_t ChannelHealth::non_finite_samples() const {
  std::int64_t total = 0;
  for (const ChannelHealthCounters& channel : counters_) total += channel.non_finite_samples;
  return total;
}

std::int64_t ChannelHealth::clipped_samples() const {
  std::int64_t total = 0;
  for (const ChannelHealthCounters& channel : counters_) total += channel.clipped_samples;
  return total;
}

void ChannelHealth::finish() {
  events_.clear();
  if (filled_ > 0 &&
      static_cast<double>(filled_) >= settings_.min_last_stretch_s * sample_rate_hz_) {
    judge(filled_);
  }
}

void ChannelHealth::observe(const ChannelRun& run) {
  if (run.channels != channels_ || run.frames == 0 || run.interleaved == nullptr) return;
  if (filled_ == 0) stretch_first_sample_ = run.first_sample;
  for (int c = 0; c < channels_; ++c) {
    const auto index = static_cast<std::size_t>(c);
    add_channel_run(c, run.interleaved, run.frames, run.first_sample, run.sums[index],
                    run.squares[index], run.peaks[index]);
  }
  filled_ += static_cast<std::int64_t>(run.frames);
  next_sample_ = run.first_sample + static_cast<std::int64_t>(run.frames);
  if (filled_ >= stretch_frames_) judge(filled_);
}

void ChannelHealth::add_channel_run(int channel, const float* interleaved, std::size_t frames,
                                    std::int64_t first_sample, double sum, double squares,
                                    double peak) {
  const auto index = static_cast<std::size_t>(channel);
  if (!std::isfinite(squares) || !(peak < settings_.clip_level)) {
    accumulate_slowly(channel, interleaved, frames, first_sample);
    return;
  }
  Stretch& stretch = stretches_[index];
  stretch.finite += static_cast<std::int64_t>(frames);
  stretch.sum += sum;
  stretch.sum_squares += squares;
  stretch.peak = std::max(stretch.peak, peak);
  counters_[index].samples += static_cast<std::int64_t>(frames);
}

// Rare: a channel with a non-finite or clipped sample in this run, sample by sample.
void ChannelHealth::accumulate_slowly(int channel, const float* interleaved, std::size_t frames,
                                      std::int64_t first_sample) {
  Stretch& stretch = stretches_[static_cast<std::size_t>(channel)];
  ChannelHealthCounters& counters = counters_[static_cast<std::size_t>(channel)];
  const auto stride = static_cast<std::size_t>(channels_);
  for (std::size_t n = 0; n < frames; ++n) {
    const double value = interleaved[n * stride + static_cast<std::size_t>(channel)];
    const std::int64_t index = first_sample + static_cast<std::int64_t>(n);
    if (!std::isfinite(value)) {
      if (stretch.first_non_finite < 0) stretch.first_non_finite = index;
      ++stretch.non_finite;
      ++counters.non_finite_samples;
      continue;
    }
    const double size = std::fabs(value);
    ++stretch.finite;
    stretch.sum += value;
    stretch.sum_squares += value * value;
    stretch.peak = std::max(stretch.peak, size);
    if (size >= settings_.clip_level) {
      if (stretch.first_clipped < 0) stretch.first_clipped = index;
      ++stretch.clipped;
      ++counters.clipped_samples;
      if (size > settings_.absurd_level) {
        if (stretch.first_absurd < 0) stretch.first_absurd = index;
        ++stretch.absurd;
        ++counters.absurd_samples;
      }
    }
  }
  counters.samples += static_cast<std::int64_t>(frames);
}

// Judges every channel on the stretch just completed (`frames` long) and starts the next.
// What one problem says makes others meaningless on the same stretch: a channel with no finite
// sample has no level; one with absurd samples has no meaningful clipping, level or mean.
void ChannelHealth::judge(std::int64_t frames) {
  const double stretch_s = static_cast<double>(frames) / sample_rate_hz_;
  const double now_s = static_cast<double>(next_sample_) / sample_rate_hz_;
  const double stretch_start_s = static_cast<double>(stretch_first_sample_) / sample_rate_hz_;
  const double dc_level = std::pow(10.0, settings_.dc_dbfs / 20.0);
  const double silence_rms = std::pow(10.0, settings_.silence_dbfs / 20.0);
  auto time_of = [&](std::int64_t sample) { return static_cast<double>(sample) / sample_rate_hz_; };
  for (int c = 0; c < channels_; ++c) {
    Stretch& stretch = stretches_[static_cast<std::size_t>(c)];
    ChannelHealthCounters& counters = counters_[static_cast<std::size_t>(c)];
    const auto total = static_cast<double>(frames);
    const bool levels = stretch.finite > 0;
    const double finite = std::max<double>(1.0, static_cast<double>(stretch.finite));
    const double mean = levels ? stretch.sum / finite : 0.0;
    const double rms = levels ? std::sqrt(stretch.sum_squares / finite) : 0.0;
    // Level judgements need most of the stretch: a channel that is mostly NaN is that.
    const bool judged = 2 * stretch.finite >= frames;
    const bool absurd = stretch.absurd > 0;
    const bool silent = judged && !absurd && rms < silence_rms;
    const bool clipped = judged && !absurd &&
                         static_cast<double>(stretch.clipped) > settings_.clipped_share * finite;
    const bool dc = judged && !absurd && !silent &&
                    (std::fabs(mean) > settings_.dc_to_rms * rms || std::fabs(mean) > dc_level);

    HealthEvent detail;
    detail.channel = c;
    detail.time_s = now_s;
    detail.stretch_s = stretch_s;
    detail.rms_dbfs = levels ? to_dbfs(rms) : kFloorDbfs;
    detail.mean = mean;
    detail.peak = stretch.peak;
    counters.problems = 0;
    detail.share = static_cast<double>(stretch.non_finite) / total;
    update(c, HealthProblem::non_finite, stretch.non_finite > 0, time_of(stretch.first_non_finite),
           now_s, detail);
    detail.share = static_cast<double>(stretch.absurd) / total;
    update(c, HealthProblem::absurd_level, absurd, time_of(stretch.first_absurd), now_s, detail);
    detail.share = 0.0;
    update(c, HealthProblem::silent, silent, stretch_start_s, now_s, detail);
    detail.share = static_cast<double>(stretch.clipped) / total;
    update(c, HealthProblem::clipped, clipped, time_of(stretch.first_clipped), now_s, detail);
    detail.share = 0.0;
    update(c, HealthProblem::dc_offset, dc, stretch_start_s, now_s, detail);

    counters.rms_dbfs = detail.rms_dbfs;
    counters.mean = mean;
    counters.peak = stretch.peak;
    stretch = Stretch{};
  }
  filled_ = 0;
}

void ChannelHealth::update(int channel, HealthProblem problem, bool present, double since_s,
                           double now_s, const HealthEvent& detail) {
  ProblemState& state =
      states_[static_cast<std::size_t>(channel)][static_cast<std::size_t>(problem)];
  ChannelHealthCounters& counters = counters_[static_cast<std::size_t>(channel)];
  if (!present) {
    state.present = false;
    state.announced = false;
    return;
  }
  if (!state.present) state.since_s = since_s;
  state.present = true;
  counters.problems |= health_flag(problem);
  counters.problems_seen |= health_flag(problem);
  if (state.announced || now_s - state.last_raised_s < settings_.rewarn_s) return;
  state.announced = true;
  state.last_raised_s = now_s;
  if (events_.size() == events_.capacity()) return;  // never allocates (see kEventsPerProblem)
  HealthEvent event = detail;
  event.problem = problem;
  event.since_s = state.since_s;
  events_.push_back(event);
}

}  // namespace dronetrack::doa
