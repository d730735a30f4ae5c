#pragma once
// A source of multichannel audio in fixed-size blocks with sample-accurate timestamps:
// recordings (recording_source.hpp), live devices (portaudio_source.hpp), the simulator.
#include <cstdint>
#include <string>
#include <vector>

#include "doa/audio_block.hpp"

namespace dronetrack::capture {

struct SourceCounters {
  std::int64_t overruns = 0;        // blocks lost because the consumer was late (live only)
  double peak_level_dbfs = -120.0;  // of the last block's finite samples
  double rms_level_dbfs = -120.0;   // of the last block's finite samples
};

class AudioSource {
 public:
  virtual ~AudioSource() = default;
  // Fills the source's internal block and returns a view of it, or false at end of stream.
  // The view stays valid until the next call. Channel i of the view is mic i. Samples are as
  // captured (NaN/Inf and over-range included): judging them is the node's job.
  virtual bool next(doa::AudioBlockView& block) = 0;
  virtual double sample_rate_hz() const = 0;
  virtual int channels() const = 0;  // after the channel map: one per mic
  virtual const SourceCounters& counters() const = 0;
  virtual std::string describe() const = 0;  // for logs: file name or device name
  // True when the stream ended before its own declared end (a recording truncated while it was
  // being read): what was processed is a partial result.
  virtual bool cut_short() const { return false; }
};

}  // namespace dronetrack::capture
