#pragma once
// Per-channel audio health of an array node: every sample of every channel is counted as it
// arrives (non-finite, clipped, over-range), and each channel is judged over stretches of about
// a second (silence, DC offset, clipping share, absurd level). A problem is raised once when it
// appears, not per frame; a problem that clears and returns is raised again, at most once per
// rewarn_s. Plain logic: no I/O, no logging (the node adapter, apps/array_node, words and logs
// the events). Channel c is mic c of the array (0-based, after any channel map).
//
// Cost: the counting rides on the framer's one pass over each block (Framer::push with this as
// its observer: per channel a sum, a sum of squares and a peak, observe()), so the block is read
// once for both; only a channel whose run holds a non-finite or clipped sample is walked again
// sample by sample (doa_bench BM_ChannelHealth minus BM_Framer).
// Everything is sized in the constructor; observe() allocates nothing.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "doa/audio_block.hpp"

namespace dronetrack::doa {

enum class HealthProblem : std::uint8_t {
  non_finite = 0,    // NaN/inf samples (the node replaces them by 0 before its FFTs)
  silent = 1,        // RMS below silence_dbfs over a stretch (all zeros included)
  clipped = 2,       // more than clipped_share of a stretch's samples at |x| >= clip_level
  dc_offset = 3,     // |mean| > dc_to_rms x RMS, or |mean| above dc_dbfs, over a stretch
  absurd_level = 4,  // a sample beyond absurd_level x full scale (float files hold anything)
};
inline constexpr int kHealthProblemCount = 5;
// "non_finite", "silent", "clipped", "dc_offset", "absurd_level".
const char* to_string(HealthProblem problem);

// Bit i set: HealthProblem i.
using HealthFlags = std::uint8_t;
constexpr HealthFlags health_flag(HealthProblem problem) {
  return static_cast<HealthFlags>(1U << static_cast<unsigned>(problem));
}
constexpr bool has_problem(HealthFlags flags, HealthProblem problem) {
  return (flags & health_flag(problem)) != 0;
}

struct ChannelHealthSettings {
  double stretch_s = 1.0;            // each channel is judged over stretches this long
  double silence_dbfs = -100.0;      // RMS below this: silent
  double clip_level = 0.999;         // |x| at or above this (of full scale): clipped
  double clipped_share = 0.01;       // a stretch with more of its samples clipped: clipping
  double dc_to_rms = 0.9;            // |mean| above this times the RMS: DC offset
  double dc_dbfs = -20.0;            // or |mean| above this level (0.1 of full scale)
  double absurd_level = 4.0;         // |x| above this (of full scale): absurd level
  double rewarn_s = 10.0;            // a problem raised is not raised again sooner than this
  double min_last_stretch_s = 0.25;  // finish(): a shorter last stretch is not judged
};

// One channel since the start of the stream, and as judged on its last complete stretch.
struct ChannelHealthCounters {
  std::int64_t samples = 0;
  std::int64_t non_finite_samples = 0;
  std::int64_t clipped_samples = 0;  // finite, |x| >= clip_level (over-range ones included)
  std::int64_t absurd_samples = 0;   // finite, |x| > absurd_level
  HealthFlags problems = 0;          // present on the last stretch judged
  HealthFlags problems_seen = 0;     // present on any stretch so far
  double rms_dbfs = -120.0;          // of the last stretch's finite samples (floor -120)
  double mean = 0.0;                 // of the last stretch's finite samples (full scale = 1)
  double peak = 0.0;                 // largest finite |x| of the last stretch
};

// A problem raised on one channel: it appeared, and was not raised in the last rewarn_s.
struct HealthEvent {
  int channel = 0;  // 0-based: mic index
  HealthProblem problem = HealthProblem::non_finite;
  double since_s = 0.0;      // stream time it was first seen (its first sample, or its stretch)
  double time_s = 0.0;       // stream time at the end of the stretch that raised it
  double stretch_s = 0.0;    // length of that stretch
  double share = 0.0;        // non_finite/clipped/absurd_level: share of the stretch's samples
  double rms_dbfs = -120.0;  // of the stretch's finite samples
  double mean = 0.0;
  double peak = 0.0;
};

class ChannelHealth {
 public:
  // Throws std::invalid_argument naming the bad parameter.
  ChannelHealth(int channels, double sample_rate_hz, const ChannelHealthSettings& settings = {});

  // Counts one run the framer's pass has summed (Framer::push with this as its observer: the
  // node's one pass over its samples) and judges the stretch it completes: each channel's sum,
  // squares and peak of the run as they came, the samples themselves for a channel that needs
  // the per-sample path. A run holds at most run_limit() frames (the rest of the current
  // stretch); a run with another channel count or no data is ignored. events() then holds the
  // problems raised since clear_events().
  void observe(const ChannelRun& run);
  std::size_t run_limit() const { return static_cast<std::size_t>(stretch_frames_ - filled_); }
  void clear_events() { events_.clear(); }
  // End of stream: judges the last, partial stretch if it is at least min_last_stretch_s long.
  // events() then holds the problems it raised.
  void finish();

  std::span<const HealthEvent> events() const { return events_; }
  int channels() const { return channels_; }
  const ChannelHealthCounters& channel(int c) const {
    return counters_[static_cast<std::size_t>(c)];
  }
  std::span<const ChannelHealthCounters> counters() const { return counters_; }
  std::int64_t non_finite_samples() const;  // all channels
  std::int64_t clipped_samples() const;     // all channels
  const ChannelHealthSettings& settings() const { return settings_; }

 private:
  // One channel's sums over the current stretch.
  struct Stretch {
    std::int64_t finite = 0;
    double sum = 0.0;
    double sum_squares = 0.0;
    double peak = 0.0;
    std::int64_t non_finite = 0;
    std::int64_t clipped = 0;
    std::int64_t absurd = 0;
    std::int64_t first_non_finite = -1;  // sample index
    std::int64_t first_clipped = -1;
    std::int64_t first_absurd = -1;
  };
  // One problem of one channel.
  struct ProblemState {
    bool present = false;
    bool announced = false;  // raised during the current episode
    double since_s = 0.0;
    double last_raised_s = -1e300;
  };

  void add_channel_run(int channel, const float* interleaved, std::size_t frames,
                       std::int64_t first_sample, double sum, double squares, double peak);
  void accumulate_slowly(int channel, const float* interleaved, std::size_t frames,
                         std::int64_t first_sample);
  void judge(std::int64_t frames);
  void update(int channel, HealthProblem problem, bool present, double since_s, double now_s,
              const HealthEvent& detail);

  int channels_;
  double sample_rate_hz_;
  ChannelHealthSettings settings_;
  std::int64_t stretch_frames_;
  std::int64_t filled_ = 0;  // frames in the current stretch
  std::int64_t stretch_first_sample_ = 0;
  std::int64_t next_sample_ = 0;  // one past the last sample scanned
  std::vector<Stretch> stretches_;
  std::vector<ChannelHealthCounters> counters_;
  std::vector<std::array<ProblemState, kHealthProblemCount>> states_;
  std::vector<HealthEvent> events_;  // capacity fixed at construction
};

}  // namespace dronetrack::doa
