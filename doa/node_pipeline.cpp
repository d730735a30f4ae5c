// PLACEHOLDER until the DSP lands (issue 4): keeps the build linking.
#include "doa/node_pipeline.hpp"

#include <stdexcept>

namespace dronetrack::doa {

struct NodePipeline::Impl {
  ArrayGeometry geometry;
  NodeDiagnostics diagnostics;
};

NodePipeline::NodePipeline(ArrayGeometry geometry, int, const DoaParams&, double, double)
    : impl_(std::make_unique<Impl>()) {
  impl_->geometry = std::move(geometry);
  throw std::logic_error("NodePipeline not implemented yet");
}
NodePipeline::~NodePipeline() = default;
NodePipeline::NodePipeline(NodePipeline&&) noexcept = default;
NodePipeline& NodePipeline::operator=(NodePipeline&&) noexcept = default;
void NodePipeline::process(const AudioBlockView&, std::vector<DoaMeasurement>&) {}
const NodeDiagnostics& NodePipeline::diagnostics() const { return impl_->diagnostics; }
const ArrayGeometry& NodePipeline::geometry() const { return impl_->geometry; }
int NodePipeline::frame_length_samples() const { return 0; }
int NodePipeline::hop_samples() const { return 0; }

}  // namespace dronetrack::doa
