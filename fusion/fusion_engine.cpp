// PLACEHOLDER until the fusion lands (issue 5): keeps the build linking.
#include "fusion/fusion_engine.hpp"

#include <stdexcept>

namespace dronetrack::fusion {

const char* to_string(DoaVerdict verdict) {
  switch (verdict) {
    case DoaVerdict::accepted:
      return "accepted";
    case DoaVerdict::non_finite:
      return "non_finite";
    case DoaVerdict::unknown_array:
      return "unknown_array";
    case DoaVerdict::too_late:
      return "too_late";
    case DoaVerdict::duplicate:
      return "duplicate";
    case DoaVerdict::bad_direction:
      return "bad_direction";
  }
  return "unknown";
}

struct FusionEngine::Impl {
  std::vector<doa::ArrayGeometry> arrays;
  FusionCounters counters;
};

FusionEngine::FusionEngine(const FusionParams&, std::vector<doa::ArrayGeometry> arrays, double)
    : impl_(std::make_unique<Impl>()) {
  impl_->arrays = std::move(arrays);
  throw std::logic_error("FusionEngine not implemented yet");
}
FusionEngine::~FusionEngine() = default;
FusionEngine::FusionEngine(FusionEngine&&) noexcept = default;
FusionEngine& FusionEngine::operator=(FusionEngine&&) noexcept = default;
DoaVerdict FusionEngine::add(const doa::DoaMeasurement&) { return DoaVerdict::accepted; }
void FusionEngine::advance_to(double) {}
void FusionEngine::tracks_at(double, std::vector<TrackReport>&) const {}
const FusionCounters& FusionEngine::counters() const { return impl_->counters; }
const std::vector<doa::ArrayGeometry>& FusionEngine::arrays() const { return impl_->arrays; }

}  // namespace dronetrack::fusion
