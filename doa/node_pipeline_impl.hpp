#pragma once
// NodePipeline's inside, shared by its parts (node_setup.cpp: validation and construction;
// node_sources.cpp: the frame's sources, found, freed of echoes and measured again;
// node_pipeline.cpp: the frame's stages in order). Not part of its interface.
#include "doa/node_pipeline.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "doa/acoustic_features.hpp"
#include "doa/array_health.hpp"
#include "doa/bin_snr_weight.hpp"
#include "doa/carrier_fringe.hpp"
#include "doa/channel_health.hpp"
#include "doa/cone_peaks.hpp"
#include "doa/detection_gate.hpp"
#include "doa/gcc_phat.hpp"
#include "doa/ground_echo.hpp"
#include "doa/harmonic_comb.hpp"
#include "doa/ls_doa_solver.hpp"
#include "doa/node_trace.hpp"
#include "doa/source_bin_mask.hpp"
#include "doa/source_tracks.hpp"
#include "doa/spectral_frame.hpp"
#include "doa/srp_phat.hpp"
#include "doa/static_source_cancel.hpp"
#include "doa/static_source_look.hpp"
#include "doa/static_source_null.hpp"
#include "doa/tdoa_tracker.hpp"

namespace dronetrack::doa {

namespace node_detail {

inline constexpr int kMaxSources = 8;
// The free SRP looks of a frame, found or cancelled (max_sources 4 and two spare: the budget
// before max_sources went to 6; with 8 looks a skewed channel's frames found spurious second
// sources and lost the health checks' one-source frames, ArrayHealthNode.SkewedChannelNamed).
inline constexpr int kMaxFreeLooks = 6;
// With SNR weighting the static null observes a plain-PHAT look every this many frames (0.1 s
// at the default hop; it learns over static_null_learn_s = 3 s). Every 4th frame left the
// generator of the ground-interferer scene un-nulled at A2 for 10 s instead of 3 s.
inline constexpr std::int64_t kStaticNullLookFrames = 2;
// A comb of fewer lines in the band is not trusted to say which bins are a source's own.
inline constexpr int kMinOwnCombLines = 4;
// A bin off the comb whose mean phasor agreement with the source reaches this is its own (the
// SourceBinMask default: one dominant source ~1, noise or another source ~0).
inline constexpr double kOwnBinAgreement = 0.5;

std::string setup_problem(const ArrayGeometry& geometry, const DoaParams& params,
                          double sample_rate_hz, double speed_of_sound_mps);
void validate(const ArrayGeometry& geometry, const DoaParams& params, double sample_rate_hz,
              double speed_of_sound_mps);
// A node per band: several bands listed, and the config asks for each on its own.
bool splits_bands(const DoaParams& params);
// The oversample giving >= 8 lag-grid samples per period of a narrow band's centre.
int fringe_oversample(const FrequencyBand& band);

}  // namespace node_detail

using node_detail::kMaxSources;
using node_detail::kStaticNullLookFrames;

struct NodePipeline::Impl {
  Impl(ArrayGeometry geometry_in, int array_index_in, const DoaParams& params_in,
       double sample_rate_hz_in, double speed_of_sound_mps);

  struct Candidate {
    DoaSolution solution;
    std::array<PairTdoa, kMaxPairs> tdoas{};
    double coherence = 0.0;
    double time_offset_s = 0.0;  // the tracker's output delay (primary only)
    int slot = -1;               // its acoustic history (source track slot, or its index)
    bool echo_removed = false;   // tdoas measured again with its ground echo divided out
  };

  void analyse(const FrameView& frame, std::vector<DoaMeasurement>& out);
  // analyse()'s stages (node_pipeline.cpp).
  double begin_frame(const FrameView& frame);  // the frame's time, s
  void whiten(const FrameView& frame, double time_s);
  DetectionInput correlate(const FrameView& frame, double time_s);
  void track(double time_s, bool sharp);
  bool gate_frame(DetectionInput& detection, double time_s);
  bool sources_to_publish(double time_s, bool detecting);
  void find_candidates();
  bool find_further_sources();  // true: the search stopped under the SRP floor
  // follow_source_tracks: each tracked source the frame has not found yet, measured from its
  // track's lags before the free looks (node_follow.cpp).
  void follow_tracked_sources();
  bool measure_near(const Eigen::Vector3d& direction_site, std::span<PairTdoa> out,
                    DoaSolution& solution, double& power) const;
  // A followed direction within one carrier fringe of a comb source found this frame that shows
  // that source's comb, or none: the source again, not a second one (carrier_fringe.hpp).
  bool fringe_of_found(std::span<const PairTdoa> followed_tdoas,
                       const Eigen::Vector3d& follow_direction_site);
  // A found source as fringe_of_found() judges follows against it, made once a frame.
  struct FoundComb {
    bool made = false;
    bool shows_comb = false;  // >= kMinOwnCombLines lines marked
    HarmonicComb comb;
    double carrier_hz = 0.0;
    std::array<double, kMaxPairs> lags_s{};
  };
  const FoundComb& found_comb(int source);
  // The static look (static_look): the held source measured again, or a search on the frames'
  // averaged phasors; adds at most one candidate (none when max_sources are found).
  void find_static_source();
  bool follow_static_source();  // true: the held source added
  bool search_static_source();  // true: a static source added
  bool add_static_source(const Eigen::Vector3d& look_direction_site);
  // The array's pose track (if any) says it held still over the static look's hold window.
  bool array_still() const;
  // free_look_lobe_choice (node_lobe_choice.cpp): of a free look's lags and those one carrier
  // period away at each mic, the ones that align the comb the kept bins hold best; true when
  // the look moved to another lobe (look_tdoas and solution replaced).
  bool choose_lobe(std::span<PairTdoa> look_tdoas, DoaSolution& solution);
  // How many lines the comb of the steered spectrum at `lags` (kept bins) shows.
  int steered_lines(std::span<const PairTdoa> lags, HarmonicComb& comb);
  // The comb of the kept bins' power, its kept line bins into lobe_lines; returns its carrier
  // (Hz), 0 when it shows fewer than kMinOwnCombLines lines.
  double mark_kept_comb(HarmonicComb& comb);
  // A pair's agreement summed over the line bins at its lag, one carrier period later and
  // earlier (the periods' turns in lobe_lines).
  struct PairLineSums {
    double look = 0.0;
    double later = 0.0;
    double earlier = 0.0;
  };
  PairLineSums pair_line_sums(int pair, double tdoa_s) const;
  // Every pair's sums at the lags (line_sums, line_sum_pairs); returns the mean agreement of the
  // line bins with the lags over the pairs with a lag.
  double all_line_sums(std::span<const PairTdoa> lags);
  // The look's line alignment; the lobes that align the lines better at its lags moved by one
  // carrier period into lobe_order (lobes_screened, best first).
  double screen_lobes(std::span<const PairTdoa> look_tdoas, double carrier_hz);
  // lobe_tdoas: the look's lags with mic lobe / 2 read one period early (lobe even) or late.
  void shifted_lags(std::span<const PairTdoa> look_tdoas, int lobe, double period_s);
  // lobe_tdoas' moved pairs: each pair's correlation maximum nearest its shifted lag.
  void refine_lobe(std::span<const PairTdoa> look_tdoas);
  // The SRP floor for the bins the last correlation kept (node_sources.cpp).
  double kept_bins_floor() const;
  // A look's peak solved into the next candidate's place; false: refused or a duplicate.
  bool solve_look(const SrpPeak& peak, LookKind kind);
  // The next candidate, its solution and TDOAs in place, counted with its mean coherence.
  void accept_candidate();
  // Drops the bins of candidates first..last-1 from the correlation's keep mask.
  void drop_candidates(int first, int last);
  // doa.comb_look (node_comb_look.cpp): when the free search stops under the floor, the lines of
  // the comb the kept bins' power shows (comb_look_keep, comb_look_lines; 0 lines: no comb);
  // after the static look, one look on them minus the bins of the sources found from
  // first_unmasked on, which may add a candidate.
  void mark_comb_look_lines();
  // The comb the kept bins' power shows, its lines in comb_lines; returns how many lines.
  int kept_bins_comb(HarmonicComb& comb);
  int count_lines(std::span<const std::uint8_t> keep) const;  // runs of kept bins
  void comb_look(int first_unmasked);
  void mask_source(std::span<const PairTdoa> source_tdoas, bool null_observes = false);
  void null_observe();
  void null_own_look();
  bool below_horizon(const DoaSolution& solution);
  bool already_found(const Eigen::Vector3d& direction_site) const;
  // Whether a source's re-measure may narrow it to its own comb's lines (own_comb_bins): not
  // the static look's, whose direction was found on averaged phasors and is tested against all
  // the frame's bins, not only those that agree with it.
  enum class CombLines : std::uint8_t { allowed, not_allowed };
  // near_known_lags: the peaks moved by a small correction only (the ground echo's, well under
  // a grid step): Newton from the known lags, no lag grids.
  bool remeasure(int source, const GccPhat::UnitsView& units, bool near_known_lags = false,
                 CombLines comb_permission = CombLines::allowed);
  void remove_ground_echoes();
  // weighted: the phasors made with the SNR weights on (for a weighted correlation next).
  // Returns whether only the source's own comb lines are kept (keep_own_comb()).
  bool only_bins_of(int source, const GccPhat::UnitsView& units, bool weighted = false,
                    CombLines comb_permission = CombLines::allowed);
  // Drops the kept bins off the source's own harmonic comb; false (nothing dropped) when it
  // shows no comb.
  bool keep_own_comb(int source, const GccPhat::UnitsView& units);
  // The comb of a source's steered cross-power over the bins `keep` holds (into comb_power and
  // comb_agreement); pairs: how many pairs carry a lag.
  HarmonicComb steered_comb(std::span<const PairTdoa> source_tdoas, const GccPhat::UnitsView& units,
                            std::span<const std::uint8_t> keep, int& pairs);
  // Adds, over the pairs that carry a lag, each bin's agreement with the lags, cos(phase_ij -
  // w tau_ij), and its steered cross-power (times |X_i||X_j|) where `keep` (band order) is 1;
  // power and agreement are indexed by FFT bin from the band's first. Returns the pairs added.
  int steer(std::span<const PairTdoa> lags, const GccPhat::UnitsView& units,
            std::span<const std::uint8_t> keep, std::span<double> power,
            std::span<double> agreement) const;
  // The mask as it stands (static null, sources below the horizon): what every later look of
  // this frame starts from.
  void keep_frame_mask();
  void remove_ground_echo(int source, GroundEcho& echo);
  // The frame trace (set_frame_trace; node_trace.cpp): each does nothing without a sink.
  void trace_begin(double time_s);
  // look_direction_array: where a refused solution's look was (null: its own direction).
  void trace_look(LookKind kind, const DoaSolution& solution, bool duplicate,
                  const Eigen::Vector3d* look_direction_array = nullptr);
  void trace_added(LookKind kind, int first_candidate);  // candidates first_candidate.. added
  void trace_search_end(bool under_floor);
  void trace_comb_look(int line_bins,
                       double floor);  // after the comb look's correlation, before its search
  void trace_candidates();
  void trace_end(bool sharp, bool detecting);
  void smooth_candidates(double time_s);
  // This frame's sources' spectra into their slots' acoustic histories (every few frames).
  // acoustic_directions/slots/generations hold `count` sources.
  void measure_acoustics(int count);
  bool was_detecting(double time_s) const;
  // Only the per-source regression reports an earlier frame; the per-pair trackers are current.
  double output_delay_s() const { return source_tracks ? source_tracks->output_delay_s() : 0.0; }
  double mean_coherence(std::span<const PairTdoa> used) const;
  // Mean over channels; each channel's into channel_power.
  double inband_power();
  // The frame's correlations are as sharp as publishing needs, whatever their main lobes' sign:
  // a flipped mic's pairs peak negative, which neither `sharp` nor the gate's SNR (its floor
  // counts what is not coherent at the positive peaks) would call a source.
  bool sharp_either_sign() const;
  // The channels judged against each other (ArrayHealth) on this frame's powers and peaks.
  void judge_channels(double time_s, bool frame_clean, bool sharp, int frame_sources);
  bool publish(const Candidate& candidate, double time_s, int source_index,
               std::vector<DoaMeasurement>& out);
  // The pose at the DOA's time, its site-frame vectors turned to it; false: no pose then.
  bool stamp_pose(DoaMeasurement& measurement);
  // A moving array's solution from its TDOAs freed of the platform's Doppler scale.
  DoaSolution doppler_corrected(const Candidate& candidate, double time_s) const;

  ArrayGeometry geometry;
  int array_index;
  DoaParams params;
  double sample_rate_hz;
  int frame_length;
  int hop;
  LsDoaSolver solver;
  Framer framer;
  MultichannelFft fft;
  GccPhat gcc;
  DetectionGate gate;
  std::vector<BandRun> band;
  ChannelHealth health;
  ArrayHealth array_health;
  std::array<double, kMaxMics> channel_power{};    // this frame's, in band, after gains
  std::array<PairPeak, kMaxPairs> health_pairs{};  // this frame's first look's peaks
  std::unique_ptr<TdoaEstimator> tracker;
  std::unique_ptr<SrpPhat> srp;
  double srp_noise_floor = 0.0;  // a further source's SRP power must exceed this
  SourceBinMask bin_mask{gcc};
  // own_comb_bins: the comb of each source's steered cross-power (FFT bins comb_first_bin..).
  std::unique_ptr<HarmonicCombDetector> own_comb;
  int comb_first_bin = 0;
  std::vector<double> comb_power;
  std::vector<double> comb_agreement;  // sum over pairs of cos(phase_ij - w tau_ij)
  std::vector<std::uint8_t> comb_lines;
  std::vector<std::uint8_t> comb_look_keep =
      std::vector<std::uint8_t>(static_cast<std::size_t>(gcc.band_bin_count()), 0);  // band order
  int comb_look_lines = 0;
  double min_elevation_sine = std::sin(params.min_elevation_deg * std::numbers::pi / 180.0);
  double separation_cosine = std::cos(params.srp_min_separation_deg * std::numbers::pi / 180.0);
  std::unique_ptr<StaticSourceNull> static_null;      // static ground sources' bins dropped
  std::unique_ptr<StaticSourceCancel> static_cancel;  // ... or kept with the source projected out
  std::unique_ptr<StaticSourceLook> static_look;      // static sources under louder ones
  std::array<Eigen::Vector3d, kMaxSources> found_directions{};  // the own looks', for it
  std::unique_ptr<BinSnrWeight> snr_weight;                     // noise-only bins faded
  std::unique_ptr<AcousticFeatureExtractor> acoustic;           // each source's spectral features
  bool acoustic_due = false;                                    // this frame is measured
  std::array<Eigen::Vector3d, kMaxSources> acoustic_directions{};
  std::array<int, kMaxSources> acoustic_slots{};
  std::array<std::uint32_t, kMaxSources> acoustic_generations{};
  // Each source's ground reflection (its range and strength are its own), following the sources
  // by direction; empty for arrays that cannot tell the echo from the source.
  std::vector<GroundEcho> ground_echoes;
  std::unique_ptr<SourceTracks> source_tracks;
  // follow_tracked_sources()' measurements: the one being made and the best so far.
  std::array<PairTdoa, kMaxPairs> follow_tdoas{};
  std::array<PairTdoa, kMaxPairs> best_follow_tdoas{};
  DoaSolution follow_solution;
  // choose_lobe()'s line bins: the first lobe_line_count of lobe_lines (room for the band).
  struct LineBin {
    std::size_t band_index = 0;  // in the band's bins (the units' rows)
    int fft_bin = 0;
    double period_re = 0.0;  // e^{j w P}: the phase one carrier period P turns the bin by
    double period_im = 0.0;
  };
  std::vector<LineBin> lobe_lines;
  int lobe_line_count = 0;
  int lobes_screened = 0;  // of lobe_order
  std::array<PairLineSums, kMaxPairs> line_sums{};
  int line_sum_pairs = 0;
  // choose_lobe()'s lobe being judged, and the lobes by their alignment at the shifted lags.
  std::array<PairTdoa, kMaxPairs> lobe_tdoas{};
  std::array<std::pair<double, int>, 2 * kMaxMics> lobe_order{};
  DoaSolution best_follow_solution;
  std::array<FoundComb, kMaxSources> found_combs{};  // this frame's, by candidate index
  std::unique_ptr<ConePeakHistory> cone_peaks;       // rank 1 only
  std::array<SourceObservation, kMaxSources> observations{};
  std::array<SourceEstimate, kMaxSources> estimates{};
  struct FrameDetection {
    double time_s = -1e300;
    bool detecting = false;
  };
  std::array<FrameDetection, 64> recent_detections{};  // ring: was the gate open at that frame
  std::size_t next_detection = 0;
  std::vector<PairTdoa> tdoas;
  std::vector<std::uint8_t> frame_mask = std::vector<std::uint8_t>(
      static_cast<std::size_t>(gcc.band_bin_count()), 1);  // keep_frame_mask()
  std::array<Candidate, kMaxSources> candidates{};
  int candidate_count = 0;
  // This frame's static-null observation (SNR weighting on): wanted, made, and on what time and
  // frame condition.
  bool null_wanted = false;
  bool null_observed = false;
  double null_time_s = 0.0;
  bool null_frame_clean = false;
  double frame_time_s = 0.0;  // this frame's centre, s (begin_frame())
  NodeDiagnostics diagnostics;
  FrameTraceSink* trace_sink = nullptr;  // set_frame_trace(): tools only
  FrameTrace trace;
  PoseStamp fixed_pose = fixed_stamp(geometry);
  PoseTrack pose_track;            // empty: a fixed array
  double sound_speed_mps = 343.0;  // for the Doppler correction
};

}  // namespace dronetrack::doa
