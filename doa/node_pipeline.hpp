#pragma once
// One array node: blocks of multichannel audio in, directions of arrival out.
// Synchronous and preallocated: threads and queues wrap it from outside (capture/, apps/).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "doa/array_geometry.hpp"
#include "doa/array_health.hpp"
#include "doa/audio_block.hpp"
#include "doa/channel_health.hpp"
#include "doa/doa_measurement.hpp"
#include "doa/doa_params.hpp"
#include "doa/node_trace.hpp"
#include "doa/pose_track.hpp"

namespace dronetrack::doa {

struct NodeDiagnostics {
  std::int64_t frames_processed = 0;
  std::int64_t doas_published = 0;
  std::int64_t non_finite_samples = 0;  // NaN/Inf replaced by 0 and counted, all channels
  std::int64_t clipped_samples = 0;     // |x| >= 0.999, all channels (per channel: health())
  double level_dbfs = -120.0;           // RMS of the samples of the last hop, all channels
  double noise_floor_dbfs = -120.0;     // adaptive in-band noise floor
  double snr_db = 0.0;                  // in-band SNR of the last frame
  bool detecting = false;
  std::int64_t stream_gaps = 0;      // blocks whose first_sample did not follow on (reframed)
  std::int64_t rejected_blocks = 0;  // blocks with the wrong channel count or no data
  std::int64_t below_horizon_rejected = 0;  // sources below min_elevation_deg (not reported)
  std::int64_t static_look_sources = 0;     // sources the static look added (doa.static_look)
  std::int64_t followed_sources =
      0;  // sources measured from their tracks' lags (doa.follow_source_tracks)
  // Followed directions left out as a found comb source's carrier fringe (fringe_of_found()).
  std::int64_t fringes_not_followed = 0;
  // Free looks moved to a neighbouring carrier lobe that aligns the comb's lines better
  // (doa.free_look_lobe_choice).
  std::int64_t free_look_lobes_moved = 0;
  // After the free search stopped under the floor (doa.comb_look): looks made on a comb's lines,
  // and the sources they added.
  std::int64_t comb_looks = 0;
  std::int64_t comb_look_sources = 0;
  int static_sources_nulled = 0;  // ground sources whose bins are dropped (static_null)
  std::int64_t unposed_doas = 0;  // moving array: DOAs outside the pose track's span (dropped)
};

class NodePipeline {
 public:
  // Throws std::invalid_argument naming the bad parameter.
  NodePipeline(ArrayGeometry geometry, int array_index, const DoaParams& params,
               double sample_rate_hz, double speed_of_sound_mps);
  ~NodePipeline();
  NodePipeline(NodePipeline&&) noexcept;
  NodePipeline& operator=(NodePipeline&&) noexcept;
  // What would make the constructor throw, as one line ("" when the setup is valid), so a
  // config check can name the file and key before anything is allocated.
  static std::string setup_problem(const ArrayGeometry& geometry, const DoaParams& params,
                                   double sample_rate_hz, double speed_of_sound_mps);

  // Feeds any number of samples; appends to `out` the DOAs of every analysis frame completed,
  // oldest first. Several bands with DoaParams::per_band_detection: each band is a node of its
  // own (its detection, GCC, tracker and source search on its bins), and its k-th source of a
  // frame is published as source_index band + bands x k (seed 003: source i is band i).
  // Never throws on odd audio (silence, clipping, NaN, dropouts): counts it in diagnostics().
  void process(const AudioBlockView& block, std::vector<DoaMeasurement>& out);

  // A moving array (issue 15): every DOA is stamped with `track`'s pose at its time and turned
  // to that attitude; one outside the track's span is counted (unposed_doas), not published.
  // An empty track (the default): the geometry's fixed pose.
  void set_pose_track(PoseTrack track);

  // Tools only (explaining a missed source against a scene's truth): `sink` (null: none, the
  // default) receives every analysed frame's FrameTrace; it must outlive the pipeline's use.
  void set_frame_trace(FrameTraceSink* sink);

  // The stream ended: judges the audio health of its last, partial stretch (health().events()).
  void finish();

  const NodeDiagnostics& diagnostics() const;
  // Per-channel audio health; its events() are the problems raised by the last process() or
  // finish() call (docs/deployment.md "Audio health").
  const ChannelHealth& health() const;
  // The channels judged against each other (level, dead, polarity, closure, skew); its events()
  // are the problems raised by the last process() call (docs/calibration.md "Health checks at
  // the node"). Per band: the first band's.
  const ArrayHealth& array_health() const;
  const ArrayGeometry& geometry() const;
  int frame_length_samples() const;
  int hop_samples() const;
  // How far a DOA's time can trail the last sample fed: half a frame (DOAs carry their frame's
  // centre time) plus the TDOA tracker's output delay. A consumer that has fed samples up to t
  // will receive no further DOA older than t - output_latency_s().
  double output_latency_s() const;

 private:
  struct Impl;
  // Several bands with per_band_detection: a whole node per band, their DOAs merged (impl_ null).
  struct PerBand;
  std::unique_ptr<Impl> impl_;
  std::unique_ptr<PerBand> per_band_;
};

}  // namespace dronetrack::doa
