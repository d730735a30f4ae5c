// NodePipeline: the composition of the node's stages, one frame at a time:
//   Framer -> MultichannelFft -> GccPhat -> DetectionGate -> TdoaEstimator -> LsDoaSolver
//                                        \-> SrpPhat (further sources) -> LsDoaSolver
// With robust_regression the frame's sources are found per frame (per-frame peaks, then SRP),
// and SourceTracks smooths each source's TDOAs over time on one time base before the final solve.
// Beside the frames, ChannelHealth counts and judges every channel's samples as they come.
// Everything is sized in the constructor; process() only appends to the caller's vector.
// Several bands with per_band_detection (issue 15, seed 003: one source per band): PerBand runs
// one such composition per band, each on its band alone, and merges their DOAs by time.
#include "doa/node_pipeline_impl.hpp"

namespace dronetrack::doa {

using namespace node_detail;

// One frame through the node's stages, in order.
void NodePipeline::Impl::analyse(const FrameView& frame, std::vector<DoaMeasurement>& out) {
  const double time_s = begin_frame(frame);
  trace_begin(time_s);
  whiten(frame, time_s);
  DetectionInput detection = correlate(frame, time_s);
  // Sharp correlations on a clean frame: worth tracking and solving. Whether to publish also
  // needs the level over the noise floor, whose update needs the coherent power of every
  // source found, so the gate comes after the candidates.
  const bool sharp = detection.frame_clean && detection.mean_peak_value >= params.min_gcc_peak &&
                     detection.inband_power > 0.0;
  track(time_s, sharp);
  if (sharp) find_candidates();
  // Sources this frame's looks found (before the regression replaces them); none accepted on
  // a sharp frame is still one source for the health checks: a skewed channel makes its
  // delays fail the solver's fit.
  const int frame_sources = candidate_count;
  if (null_wanted && !null_observed) null_own_look();
  const bool detecting = gate_frame(detection, time_s);
  judge_channels(time_s, detection.frame_clean, sharp, frame_sources);
  trace_end(sharp, detecting);
  if (!sources_to_publish(time_s, detecting)) return;
  for (int s = 0; s < candidate_count; ++s) {
    const Candidate& candidate = candidates[static_cast<std::size_t>(s)];
    publish(candidate, time_s - candidate.time_offset_s, s, out);
  }
}

double NodePipeline::Impl::begin_frame(const FrameView& frame) {
  ++diagnostics.frames_processed;
  diagnostics.level_dbfs = 10.0 * std::log10(std::max(frame.recent_mean_square, 1e-20));
  candidate_count = 0;
  for (Candidate& candidate : candidates) candidate.echo_removed = false;
  frame_time_s =
      (static_cast<double>(frame.first_sample) + 0.5 * (frame.length - 1)) / sample_rate_hz;
  return frame_time_s;
}

// Spectra, PHAT units and cross-power, the SNR weights, the static sources' bins dropped.
void NodePipeline::Impl::whiten(const FrameView& frame, double time_s) {
  fft.process(frame);
  gcc.whiten(fft);
  if (static_look) static_look->accumulate(gcc);
  if (snr_weight) snr_weight->update(gcc.band_powers(), gcc.unit_channels(), gcc.bin_weight());
  if (static_null) static_null->mask(time_s, gcc);
  if (static_cancel) static_cancel->apply(gcc);
}

// Every pair's correlation and peaks, and what the detection gate will judge of them.
DetectionInput NodePipeline::Impl::correlate(const FrameView& frame, double time_s) {
  const bool frame_clean =
      frame.non_finite_samples == 0 &&
      frame.clipped_samples <= static_cast<int>(params.max_clipped_fraction * frame.length);
  null_wanted =
      static_null && snr_weight && diagnostics.frames_processed % kStaticNullLookFrames == 0;
  null_observed = false;
  null_time_s = time_s;
  null_frame_clean = frame_clean;
  if (null_wanted) keep_frame_mask();  // for null_own_look()
  gcc.correlate();
  // The health checks read the full band's first look (later looks drop bins).
  for (int p = 0; p < gcc.pair_count(); ++p) {
    PairPeak& pair = health_pairs[static_cast<std::size_t>(p)];
    pair = correlation_extremes(gcc.grid(p));
    pair.tdoa_s = gcc.pair(p).peak.lag_s;
  }
  if (cone_peaks) cone_peaks->record(time_s, gcc);
  double coherence_sum = 0.0;
  double peak_sum = 0.0;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    coherence_sum += gcc.pair(p).coherence;
    peak_sum += gcc.pair(p).peak.value;
  }
  DetectionInput detection;
  detection.inband_power = inband_power();
  detection.mean_peak_value = peak_sum / gcc.pair_count();
  detection.frame_clean = frame_clean;
  detection.mean_coherence = coherence_sum / gcc.pair_count();  // gate_frame(): sources' share
  return detection;
}

// The per-pair TDOAs (and the static null's observation without SNR weights).
void NodePipeline::Impl::track(double time_s, bool sharp) {
  if (static_null && !snr_weight) {
    static_null->observe(time_s, gcc, sharp);
    diagnostics.static_sources_nulled = static_null->nulled_count();
  }
  tracker->update(time_s, gcc, sharp, tdoas);
  acoustic_due = acoustic && acoustic->due(diagnostics.frames_processed);
}

// The detection gate on the frame's level and its sources' coherent share.
bool NodePipeline::Impl::gate_frame(DetectionInput& detection, double time_s) {
  double coherent_share = 0.0;
  for (int s = 0; s < candidate_count; ++s)
    coherent_share += candidates[static_cast<std::size_t>(s)].coherence;
  if (candidate_count == 0) coherent_share = detection.mean_coherence;
  detection.mean_coherence = std::min(coherent_share, 0.999);
  const bool detecting = gate.update(detection);
  diagnostics.noise_floor_dbfs = gate.noise_floor_dbfs();
  diagnostics.snr_db = gate.snr_db();
  diagnostics.detecting = detecting;
  recent_detections[next_detection] = {time_s, detecting};
  next_detection = (next_detection + 1) % recent_detections.size();
  return detecting;
}

void NodePipeline::Impl::judge_channels(double time_s, bool frame_clean, bool sharp,
                                        int frame_sources) {
  // One source found and its ground echo divided out: its delays measured again feed the
  // closure and the delay fit. The first look's peaks carry the echo, whose pull on the pairs
  // holding the top mic changes with the elevation as a delay on that mic would.
  const Candidate& first = candidates.front();
  const bool echo_free = frame_sources == 1 && first.echo_removed && first.time_offset_s == 0.0;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairTdoa& own = first.tdoas[static_cast<std::size_t>(p)];
    health_pairs[static_cast<std::size_t>(p)].source_tdoa_s =
        echo_free && own.variance_s2 > 0.0 ? own.tdoa_s : std::numeric_limits<double>::quiet_NaN();
  }
  array_health.observe(
      time_s,
      std::span<const double>(channel_power.data(), static_cast<std::size_t>(fft.channels())),
      std::span<const PairPeak>(health_pairs.data(), static_cast<std::size_t>(gcc.pair_count())),
      frame_clean && (gate.snr_db() >= params.detection_snr_db || sharp_either_sign()),
      sharp && frame_sources <= 1);
}

// The candidates become the sources to publish (smoothed over frames with the per-source
// regression), their acoustic features measured; false: nothing to publish this frame.
bool NodePipeline::Impl::sources_to_publish(double time_s, bool detecting) {
  if (source_tracks) {
    smooth_candidates(time_s);
    // The estimates are for an earlier frame: that frame's gate decides.
    return candidate_count == 0 || was_detecting(time_s - source_tracks->output_delay_s());
  }
  // The per-pair trackers' sources have no identity over frames but their rank.
  for (int s = 0; s < candidate_count; ++s) {
    Candidate& candidate = candidates[static_cast<std::size_t>(s)];
    candidate.slot = s;
    acoustic_directions[static_cast<std::size_t>(s)] = candidate.solution.direction_site;
    acoustic_slots[static_cast<std::size_t>(s)] = s;
    acoustic_generations[static_cast<std::size_t>(s)] = 0;
  }
  if (acoustic_due) measure_acoustics(candidate_count);
  return detecting;
}

// Per-band detection: a node per band, each a whole NodePipeline on that band's bins alone (its
// own framer, FFT, GCC, detection gate, TDOA tracker, multi-source search, cone peaks and source
// tracks; FFTW plans made in their constructors). Every band's DOAs of one process() call are
// collected in that band's reused vector and merged into the caller's oldest first (one frame's
// sources: band order). The cost is the single-band node's per band, FFT included (docs/doa.md).
struct NodePipeline::PerBand {
  std::vector<NodePipeline> nodes;
  std::vector<std::vector<DoaMeasurement>> outputs;  // per band, this call's DOAs
  std::vector<std::size_t> next;                     // per band, the merge's cursor
  NodeDiagnostics diagnostics;

  void process(const AudioBlockView& block, std::vector<DoaMeasurement>& out);
  void merge_diagnostics();
};

void NodePipeline::PerBand::process(const AudioBlockView& block, std::vector<DoaMeasurement>& out) {
  const auto bands = static_cast<int>(nodes.size());
  for (std::size_t b = 0; b < nodes.size(); ++b) {
    outputs[b].clear();
    nodes[b].process(block, outputs[b]);
    for (DoaMeasurement& doa : outputs[b])
      doa.source_index = static_cast<int>(b) + bands * doa.source_index;
    next[b] = 0;
  }
  for (;;) {
    std::size_t oldest = nodes.size();
    for (std::size_t b = 0; b < nodes.size(); ++b) {
      if (next[b] >= outputs[b].size()) continue;
      if (oldest == nodes.size() ||
          outputs[b][next[b]].time_s < outputs[oldest][next[oldest]].time_s)
        oldest = b;
    }
    if (oldest == nodes.size()) break;
    out.push_back(std::move(outputs[oldest][next[oldest]++]));
  }
  merge_diagnostics();
}

// The samples' counters are every band's (each node sees every sample): the first band's. The
// DOAs' counters add up; the node detects when any band does, at the best band's SNR, over the
// bands' noise floors together.
void NodePipeline::PerBand::merge_diagnostics() {
  diagnostics = nodes.front().diagnostics();
  diagnostics.doas_published = 0;
  diagnostics.below_horizon_rejected = 0;
  diagnostics.static_sources_nulled = 0;
  diagnostics.unposed_doas = 0;
  diagnostics.detecting = false;
  diagnostics.snr_db = -1e300;
  double floor_power = 0.0;
  for (const NodePipeline& node : nodes) {
    const NodeDiagnostics& band = node.diagnostics();
    diagnostics.doas_published += band.doas_published;
    diagnostics.below_horizon_rejected += band.below_horizon_rejected;
    diagnostics.static_sources_nulled += band.static_sources_nulled;
    diagnostics.unposed_doas += band.unposed_doas;
    diagnostics.detecting = diagnostics.detecting || band.detecting;
    diagnostics.snr_db = std::max(diagnostics.snr_db, band.snr_db);
    floor_power += std::pow(10.0, band.noise_floor_dbfs / 10.0);
  }
  diagnostics.noise_floor_dbfs = 10.0 * std::log10(std::max(floor_power, 1e-30));
}

NodePipeline::NodePipeline(ArrayGeometry geometry, int array_index, const DoaParams& params,
                           double sample_rate_hz, double speed_of_sound_mps) {
  validate(geometry, params, sample_rate_hz, speed_of_sound_mps);
  if (splits_bands(params)) {
    per_band_ = std::make_unique<PerBand>();
    for (const FrequencyBand& band : params.bands_hz) {
      DoaParams one_band = params;
      one_band.bands_hz = {band};
      one_band.correlation_oversample =
          std::max(params.correlation_oversample, fringe_oversample(band));
      per_band_->nodes.emplace_back(geometry, array_index, one_band, sample_rate_hz,
                                    speed_of_sound_mps);
    }
    per_band_->outputs.resize(params.bands_hz.size());
    per_band_->next.assign(params.bands_hz.size(), 0);
    per_band_->merge_diagnostics();
    return;
  }
  impl_ = std::make_unique<Impl>(std::move(geometry), array_index, params, sample_rate_hz,
                                 speed_of_sound_mps);
  impl_->sound_speed_mps = speed_of_sound_mps;
}
NodePipeline::~NodePipeline() = default;
NodePipeline::NodePipeline(NodePipeline&&) noexcept = default;
NodePipeline& NodePipeline::operator=(NodePipeline&&) noexcept = default;

void NodePipeline::process(const AudioBlockView& block, std::vector<DoaMeasurement>& out) {
  if (per_band_) {
    per_band_->process(block, out);
    return;
  }
  Impl& impl = *impl_;
  // The samples' health counted as they came (the framer replaces the non-finite ones by 0),
  // from the framer's own pass over them: one read of the block serves both.
  impl.health.clear_events();
  impl.array_health.clear_events();
  impl.framer.push(
      block, [&](const FrameView& frame) { impl.analyse(frame, out); }, impl.health);
  const FramerCounters& counters = impl.framer.counters();
  impl.diagnostics.non_finite_samples = impl.health.non_finite_samples();
  impl.diagnostics.clipped_samples = impl.health.clipped_samples();
  impl.diagnostics.stream_gaps = counters.stream_gaps;
  impl.diagnostics.rejected_blocks = counters.rejected_blocks;
}

void NodePipeline::set_pose_track(PoseTrack track) {
  if (per_band_) {
    for (NodePipeline& node : per_band_->nodes) node.set_pose_track(track);
    return;
  }
  impl_->pose_track = std::move(track);
}

void NodePipeline::set_frame_trace(FrameTraceSink* sink) {
  if (per_band_) {
    for (NodePipeline& node : per_band_->nodes) node.set_frame_trace(sink);
    return;
  }
  impl_->trace_sink = sink;
  const auto bins = static_cast<std::size_t>(impl_->gcc.band_bin_count());
  impl_->trace.kept_after_null.assign(bins, 1);
  impl_->trace.kept_at_search_end.assign(bins, 1);
}

void NodePipeline::finish() {
  if (per_band_) {
    for (NodePipeline& node : per_band_->nodes) node.finish();
    return;
  }
  impl_->health.finish();
  impl_->array_health.clear_events();  // the last process() call's were handed out
}

// Per band: every band's node frames the same samples with the same frame and hop.
const NodeDiagnostics& NodePipeline::diagnostics() const {
  return per_band_ ? per_band_->diagnostics : impl_->diagnostics;
}
const ChannelHealth& NodePipeline::health() const {
  return per_band_ ? per_band_->nodes.front().health() : impl_->health;
}
const ArrayHealth& NodePipeline::array_health() const {
  return per_band_ ? per_band_->nodes.front().array_health() : impl_->array_health;
}
const ArrayGeometry& NodePipeline::geometry() const {
  return per_band_ ? per_band_->nodes.front().geometry() : impl_->geometry;
}
int NodePipeline::frame_length_samples() const {
  return per_band_ ? per_band_->nodes.front().frame_length_samples() : impl_->frame_length;
}
int NodePipeline::hop_samples() const {
  return per_band_ ? per_band_->nodes.front().hop_samples() : impl_->hop;
}
double NodePipeline::output_latency_s() const {
  if (per_band_) {
    double latency_s = 0.0;
    for (const NodePipeline& node : per_band_->nodes)
      latency_s = std::max(latency_s, node.output_latency_s());
    return latency_s;
  }
  return (0.5 * impl_->frame_length + 1.0) / impl_->sample_rate_hz + impl_->output_delay_s();
}

}  // namespace dronetrack::doa
