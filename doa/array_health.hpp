#pragma once
// Health of an array's channels judged against each other, online, from what the node's
// pipeline computes every frame anyway (issue 16): each channel's in-band power after the
// calibrated gains, and every mic pair's GCC-PHAT peak (its refined lag and the signed largest
// value of its correlation). Six problems, each raised once when it appears (as ChannelHealth):
//   level_imbalance  a channel's in-band level off the array's median by more than imbalance_db;
//   dead             a channel far below the median (dead_level_db), or incoherent with every
//                    other mic while the other pairs hear a source;
//   polarity_flipped the pairs holding the channel correlate with a negative main lobe on the
//                    frames with a source, the others with a positive one;
//   closure          the pair delays of one source do not add up (tau_ij + tau_jk - tau_ik != 0,
//                    running median per triple) on the triples holding the channel;
//   skew             the channel's delay, fitted from the pair delays' misfit to a plane wave
//                    over many source directions (ChannelDelayFit), is off the median
//                    channel's by several of its cluster-robust standard deviations;
//   swapped          two channels wired to each other's inputs: the pair delays with the two
//                    relabelled fit a plane wave decisively better than as wired. Closure cannot
//                    see it (a relabelling keeps every sum), nor can anything at one node when
//                    the swap is a symmetry of the array (a regular tetrahedron's every swap is a
//                    mirror: the swapped array hears the mirror world exactly); such swaps are
//                    not tested here (swap_observable()): the fusion names them against tracks
//                    the other arrays fix (fusion/array_mirror_check.hpp).
// A pure per-channel delay d cancels exactly in a closure sum ((d_i - d_j) + (d_j - d_k) -
// (d_i - d_k) = 0); closure catches the GCC picking different sources or cycles on different
// pairs, which is what a skewed channel does to a harmonic drone, and the delay fit catches the
// skew itself. Thresholds and their units: docs/calibration.md "Health checks at the node".
// Plain logic (Eigen, std): no I/O, no clock; everything sized in the constructor, observe()
// allocates nothing.
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "doa/array_geometry.hpp"
#include "doa/channel_delay_fit.hpp"
#include "doa/doa_measurement.hpp"

namespace dronetrack::doa {

enum class ArrayProblem : std::uint8_t {
  level_imbalance = 0,
  dead = 1,
  polarity_flipped = 2,
  closure = 3,
  skew = 4,
  swapped = 5,
};
inline constexpr int kArrayProblemCount = 6;
// "level_imbalance", "dead", "polarity_flipped", "closure", "skew", "swapped".
const char* to_string(ArrayProblem problem);

// Bit i set: ArrayProblem i.
using ArrayFlags = std::uint8_t;
constexpr ArrayFlags array_flag(ArrayProblem problem) {
  return static_cast<ArrayFlags>(1U << static_cast<unsigned>(problem));
}
constexpr bool has_problem(ArrayFlags flags, ArrayProblem problem) {
  return (flags & array_flag(problem)) != 0;
}
inline constexpr ArrayFlags kKnownArrayProblems = (1U << kArrayProblemCount) - 1;

struct ArrayHealthSettings {
  double level_stretch_s = 2.0;    // levels are compared over stretches this long
  double imbalance_db = 3.0;       // |level offset| above this: level_imbalance
  double dead_level_db = -20.0;    // level offset below this: dead
  double coherent_peak = 0.2;      // |GCC peak| at or above this: the pair hears a source
  double incoherent_ratio = 0.3;   // a channel's best pair under this x the others' median
  double sign_dominance = 1.5;     // a main lobe's sign counts when |it| >= this x the other's
  int judge_source_frames = 20;    // dead (incoherent) and polarity: judged per this many
  double problem_share = 0.8;      // of those frames (incoherent) or of a pair's (negative)
  int closure_window_frames = 32;  // running median of each triple's closure over these
  double closure_us = 40.0;        // |median closure| above this: the triple is off
  int closure_persistence = 3;     // and fails when off on this many judgements in a row
  double frame_closure_us = 30.0;  // a frame with a larger closure feeds no delay fit
  double skew_sigmas = 6.0;        // a channel's delay offset this many of its std off 0
  double min_skew_us = 10.4;       // and over this (half a sample: the node sets it)
  int min_skew_sectors = 8;        // direction sectors seen before a delay is judged
  int skew_sectors = 32;           // the sphere's direction sectors (ChannelDelayFit)
  double skew_window_s = 30.0;     // the delay fit forgets with this time constant
  double skew_prior_us = 1000.0;   // channel delays a priori (keeps unseen ones at 0)
  double min_skew_frames = 200.0;  // source frames (forgetting-weighted) before judging it
  double min_swap_frames = 60.0;   // source frames (forgetting-weighted) before judging swaps
  double swap_evidence_us = 5.0;   // a swap must lower the RMS plane-wave misfit by this much
  double swap_misfit_ratio = 0.5;  // and to at most this share of the misfit as wired
  double rewarn_s = 10.0;          // a problem raised is not raised again sooner than this
};

// One mic pair on one frame (pairs i<j in lexicographic order, tau_ij = t_i - t_j).
struct PairPeak {
  double tdoa_s = 0.0;   // the refined highest peak's lag
  double highest = 0.0;  // the correlation's largest value over the physical lags (>= 0)
  double lowest = 0.0;   // and its smallest (<= 0)
  // The frame's one source's delay measured again with its ground echo divided out; NaN when
  // there is none. Closure and the delay fit take it in place of tdoa_s; the swap check takes
  // tdoa_s, which no model of the array has touched.
  double source_tdoa_s = std::numeric_limits<double>::quiet_NaN();
};

// The largest and smallest values of a pair's correlation (lags within the physical limit),
// clamped to >= 0 and <= 0: a PairPeak without its lag.
PairPeak correlation_extremes(std::span<const double> correlation);

struct ArrayChannelHealth {
  ArrayFlags problems = 0;       // present on the last judgement of each check
  ArrayFlags problems_seen = 0;  // present at any time so far
  double level_offset_db = 0.0;  // in-band level minus the array's median, last stretch
  double delay_offset_us = 0.0;  // fitted channel delay minus the median channel's
  double delay_std_us = std::numeric_limits<double>::infinity();  // its std (inf: not judged)
};

// A problem raised on one channel.
struct ArrayHealthEvent {
  int channel = 0;  // 0-based mic index
  ArrayProblem problem = ArrayProblem::level_imbalance;
  double time_s = 0.0;               // stream time of the judgement that raised it
  double level_offset_db = 0.0;      // the channel's, then
  double delay_offset_us = 0.0;      // the channel's, then
  double delay_std_us = 0.0;         // and its std
  int delay_sectors = 0;             // skew: the direction sectors the fit had seen
  double closure_residual_us = 0.0;  // the array's, then
  double share = 0.0;      // dead (incoherent)/polarity: share of the judged frames that showed it
  int other_channel = -1;  // swapped: the channel it is wired with
  double wired_misfit_us = 0.0;    // swapped: RMS plane-wave misfit of the delays as wired
  double swapped_misfit_us = 0.0;  // and with the two channels relabelled
};

class ArrayHealth {
 public:
  // Throws std::invalid_argument naming the bad parameter.
  ArrayHealth(const ArrayGeometry& geometry, double speed_of_sound_mps, double hop_s,
              const ArrayHealthSettings& settings = {});

  // One analysis frame: channel_power[c] (in-band power of channel c, after calibrated gains),
  // pairs[p] (every pair's peak), whether the frame carries a source (clean, over the noise
  // floor) and whether the node found exactly one (closure and the delay fit need one source:
  // with two, pairs follow different ones). Spans of the wrong size are ignored. Appends to
  // events() what this frame raised.
  void observe(double time_s, std::span<const double> channel_power,
               std::span<const PairPeak> pairs, bool source, bool single_source);
  // Forgets the events (the node calls it before each block).
  void clear_events() { events_.clear(); }

  std::span<const ArrayHealthEvent> events() const { return events_; }
  int channels() const { return channels_; }
  std::span<const ArrayChannelHealth> channel_health() const { return channels_health_; }
  // Largest |running median closure| over the triples (us), 0 before any is judged.
  double closure_residual_us() const { return closure_residual_us_; }
  // Running median over source frames of the RMS misfit of the pair delays to a plane wave of
  // unit slowness (us): grows for a moved mic or a skewed channel; 0 before any.
  double fit_residual_us() const { return fit_residual_us_; }
  const ArrayHealthSettings& settings() const { return settings_; }
  // The skew check's delay fit (ChannelDelayFit): the direction sectors it has seen, and the
  // slowness's scale error it found; 0 for arrays without one (planar, linear, two mics).
  int delay_sectors_seen() const { return delay_fit_ ? delay_fit_->sectors_seen() : 0; }
  double slowness_scale_error() const { return delay_fit_ ? delay_fit_->scale_error() : 0.0; }
  // Whether swapping channels a and b leaves a plane-wave misfit the swap check can see: its
  // RMS over the sphere of directions is at least swap_evidence_us. False for a swap that is a
  // symmetry of the array (every swap of a regular tetrahedron), and for arrays without a fit.
  bool swap_observable(int a, int b) const;
  // RMS over the sphere of directions of the misfit a swap of a and b leaves (us).
  double swap_signature_us(int a, int b) const;

 private:
  using PairVector = ChannelDelayFit::PairVector;
  using PairBySpace = ChannelDelayFit::PairBySpace;
  using SpaceByPair = Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxPairs>;
  struct ProblemState {
    bool present = false;
    bool announced = false;
    double last_raised_s = -1e300;
  };

  void observe_levels(double time_s, std::span<const double> channel_power);
  void observe_coherence(double time_s, std::span<const PairPeak> pairs);
  void observe_closure(std::span<const PairPeak> pairs);
  void judge_delays(double time_s);
  void observe_fit(std::span<const PairPeak> pairs);
  void judge_closure(double time_s);
  void judge_skew(double time_s);
  void observe_swaps(double wired_square);
  void judge_swaps(double time_s);
  // The mean over pairs of the squared misfit of `tdoas` to a plane wave of unit slowness (s^2);
  // NaN when they give no slowness.
  double plane_wave_misfit_square(const PairVector& tdoas) const;
  // `tdoas` with the channels of transposition t relabelled into `out`.
  void relabel(int transposition, const PairVector& tdoas, PairVector& out) const;
  int transposition_index(int a, int b) const;
  void update(int channel, ArrayProblem problem, bool present, double time_s, double share,
              bool announce = true);
  bool coherent_positive(const PairPeak& pair) const;
  // +1 positive main lobe, -1 negative, 0 neither dominates or too weak.
  int lobe_sign(const PairPeak& pair) const;

  int channels_;
  int pairs_;
  double speed_of_sound_mps_;
  ArrayHealthSettings settings_;
  std::vector<std::array<int, 2>> pair_mics_{};
  std::vector<std::array<int, 3>> triples_{};       // i < j < k
  std::vector<std::array<int, 3>> triple_pairs_{};  // pairs ij, jk, ik
  std::vector<ArrayChannelHealth> channels_health_{};
  std::vector<std::array<ProblemState, kArrayProblemCount>> states_{};
  std::vector<ArrayHealthEvent> events_{};  // capacity fixed at construction
  // Levels over the current stretch.
  std::vector<double> power_sums_{};
  int level_frames_ = 0;
  int level_stretch_frames_ = 1;
  std::vector<double> scratch_{};  // medians (channels, triples, window)
  // Coherence and sign over the current judgement's source frames.
  int source_frames_ = 0;
  std::vector<int> incoherent_frames_{};         // per channel
  std::vector<std::uint8_t> level_dead_{};       // per channel: the last level judgement's
  std::vector<std::uint8_t> incoherent_dead_{};  // per channel: the last coherence judgement's
  std::vector<int> coherent_frames_{};           // per pair
  std::vector<int> negative_frames_{};           // per pair
  // Closure: ring of each triple's last residuals (s), and the frames since the last judgement.
  std::vector<double> closure_ring_{};  // triple-major
  std::vector<int> closure_count_{};    // per triple, entries in the ring (up to the window)
  std::vector<int> closure_next_{};
  int closure_new_frames_ = 0;
  std::vector<int> closure_failing_runs_{};  // per triple: judgements in a row it was off
  double closure_residual_us_ = 0.0;
  std::vector<double> fit_ring_{};
  int fit_count_ = 0;
  int fit_next_ = 0;
  double fit_residual_us_ = 0.0;
  // Plane-wave fits (rank-3 arrays): the swap check's misfits and the delay fit.
  bool fit_possible_ = false;
  PairBySpace geometry_{};          // G: row (i,j) = (p_j - p_i), tau = G u / c
  SpaceByPair geometry_inverse_{};  // G^+
  double forgetting_ = 1.0;
  std::optional<ChannelDelayFit> delay_fit_{};
  std::vector<std::uint8_t> previous_skewed_{};  // per channel, the last judgement's
  int delay_sectors_ = 0;                        // the fit's sectors seen, last judgement
  PairVector frame_tdoas_{};
  // Swap check: per transposition (a < b, lexicographic), the source pair and sign of each pair
  // after relabelling, the misfit it leaves over the sphere, and the forgetting-weighted sums of
  // squared misfits (index 0: as wired, 1 + t: transposition t).
  std::vector<std::array<int, 2>> transpositions_{};
  std::vector<int> relabel_source_{};   // transposition-major, per pair
  std::vector<double> relabel_sign_{};  // transposition-major, per pair
  std::vector<double> swap_signature_us_{};
  std::vector<double> swap_square_sums_{};
  double swap_frames_ = 0.0;
  int swap_candidate_ = -1;  // the transposition the last judgement favoured
  int swap_flagged_ = -1;    // the transposition flagged, -1 none
  struct SwapEvidence {
    int other_channel = -1;
    double wired_misfit_us = 0.0;
    double swapped_misfit_us = 0.0;
  };
  SwapEvidence swap_event_{};  // the flagged swap's, for its event
  PairVector relabelled_{};
};

}  // namespace dronetrack::doa
