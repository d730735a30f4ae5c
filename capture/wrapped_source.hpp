#pragma once
// An AudioSource that changes how another one's blocks are handed out (skipped, paced) and
// passes everything else on: subclasses override next() only.
#include <memory>
#include <string>

#include "capture/audio_source.hpp"

namespace dronetrack::capture {

class WrappedSource : public AudioSource {
 public:
  explicit WrappedSource(std::unique_ptr<AudioSource> inner) : inner_(std::move(inner)) {}
  double sample_rate_hz() const override { return inner_->sample_rate_hz(); }
  int channels() const override { return inner_->channels(); }
  const SourceCounters& counters() const override { return inner_->counters(); }
  std::string describe() const override { return inner_->describe(); }
  bool cut_short() const override { return inner_->cut_short(); }

 protected:
  AudioSource& inner() { return *inner_; }

 private:
  std::unique_ptr<AudioSource> inner_;
};

}  // namespace dronetrack::capture
