#pragma once
// FusionEngine's state and stages, shared by the files that implement them (fusion/README.md):
// fusion_engine.cpp (queue, the frame loop, outputs), track_initiation.cpp, track_handover.cpp,
// manoeuvre_onset.cpp, track_life_cycle.cpp. Not part of the fusion's interface.
#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "common/log.hpp"
#include "fusion/array_mirror_check.hpp"
#include "fusion/assignment.hpp"
#include "fusion/doa_likelihood.hpp"
#include "fusion/fusion_engine.hpp"
#include "fusion/measurement_model.hpp"
#include "fusion/outlier_share.hpp"
#include "fusion/track_classifier.hpp"
#include "fusion/track_confirmation.hpp"
#include "fusion/track_filter.hpp"
#include "fusion/track_record.hpp"
#include "fusion/triangulation.hpp"

namespace dronetrack::fusion {

inline constexpr double kRadPerDeg = std::numbers::pi / 180.0;
// A DOA no track took seeds a new one only once the DOAs of the next frames are in (a hop is
// 0.05 s): every array that heard that moment can then vote between the pairings.
inline constexpr double kInitiationDelayS = 0.06;
inline constexpr std::size_t kMaxPendingSeeds = 256;
// Manoeuvre onset (issue 17): a DOA beyond a track's gate is an outlier or the track falling
// behind a manoeuvre. Outliers are independent from frame to frame; a manoeuvre makes the
// array's next DOA agree with this one. Two consecutive such DOAs of one array (no more than
// kManoeuvreRunGapS apart) that agree with each other, within the reach of a manoeuvre of the
// widest IMM jerk level lasting kManoeuvreSpanS, widen the track by that manoeuvre's process noise.
inline constexpr double kManoeuvreRunGapS = 0.2;
inline constexpr double kManoeuvreSpanS = 0.5;
// Impulsive DOA errors (alpha-stable, a few degrees' scale) land mostly within this of the source.
inline constexpr double kBesideAngleRad = 20.0 * std::numbers::pi / 180.0;

// A one-array Gaussian-sum track whose count of live branches (the locus's mirror sides) changed:
// one debug line (seed 003's "mirror hypotheses gone", docs/replicas.md measures it by this).
void log_branches(Track& track, double time_s);

// What every stage of one frame reads: its DOAs (queue[begin, end)), array, time and kind, and
// the array's outlier share e as it stood before the frame (gate, cost and update alike).
struct Frame {
  std::size_t begin = 0;
  std::size_t end = 0;
  int array = 0;
  double time_s = 0.0;
  int doa_count = 0;
  int track_count = 0;
  int dimension = 2;
  doa::DoaAmbiguity ambiguity = doa::DoaAmbiguity::none;
  OutlierShareEstimate* outlier_share = nullptr;
  std::optional<double> share;
};

struct FusionEngine::Impl {
  FusionParams params;
  std::vector<doa::ArrayGeometry> arrays;
  std::vector<DoaMeasurementModel> models;
  FilterSettings filter_settings;
  FusionCounters counters;
  std::optional<TrackClassifier> classifier;
  double gate_chi2 = 0.0;             // 2 dof: initiation, and the Gaussian likelihood's track gate
  double gate_chi2_1d = 0.0;          // the same for a cone's 1-D measurement
  FilterSettings one_array_settings;  // the one-array localisers' (issue 15)
  std::vector<Eigen::Vector3d> last_centre_m;  // each array's centre at its newest frame
  DoaMeasurementModel frame_model;  // the current frame's (pose, ambiguity); innovations point here
  std::optional<DoaLikelihood> likelihood;  // the tracks' gate, assignment cost and update
  // Per array, the outlier mixture's e (adaptive_outlier_probability; else empty).
  std::vector<OutlierShareEstimate> outlier_shares;
  double floor_variance_rad2 = 0.0;
  const double beside_cosine = std::cos(kBesideAngleRad);

  std::vector<doa::DoaMeasurement> queue;  // sorted by (time, array, source)
  double fed_time_s = kNeverS;             // newest time handed to the tracker
  std::vector<double> last_fed_time_by_array;
  std::vector<std::uint64_t> last_fed_sources_by_array;

  std::vector<Track> tracks;
  std::vector<RecentRing> recent;
  int next_id = 1;
  // Per-frame workspace, reused.
  Assignment assignment;
  std::vector<double> cost;
  std::vector<double> distance2;  // per (track, DOA) as cost: the gate's d^2, kept for e
  std::vector<int> track_to_doa;
  std::vector<char> doa_taken;
  std::vector<char> doa_confirmed;  // taken by a confirmed track
  std::vector<int> weak_claimant;   // per DOA of the frame: RecentDoa::weak_claimant_id
  std::vector<Ray> rays;
  // Issue 16: per array, the swap check against tracks the other arrays fix; its references
  // (directions to those tracks, reused) and the swaps named not yet taken.
  std::vector<ArrayMirrorCheck> mirror_checks;
  std::vector<Eigen::Vector3d> references;
  std::vector<MirrorSwapEvent> mirror_events;

  void feed_until(double cutoff_s);
  // The frame's DOAs against the tracks that arrays other than `array` fix, before this frame
  // updates them (a track the array itself pulled would read back what it put in).
  void check_mirror(int array, std::size_t begin, std::size_t end, double time_s);
  // One frame (one array, one time): its stages in order.
  void process_frame(std::size_t begin, std::size_t end);
  Frame begin_frame(std::size_t begin, std::size_t end);
  // Predict every track to the frame, gate its DOAs, and cost each pair: cost = d^2 + ln det S
  // (the negative log-likelihood up to a constant), so a vague track does not steal DOAs from a
  // sharp one.
  void gate(const Frame& frame);
  // Each track's assigned DOA: a triangulation re-fix of a one-array or open-range track, else
  // the filter's update; the bookkeeping (record_update, the outlier-born count, the one-array
  // hand-over).
  void update_assigned(const Frame& frame);
  // Confirmed tracks the frame gave no DOA: the manoeuvre onset test (follow_manoeuvre).
  void follow_manoeuvres(const Frame& frame);
  // The frame's DOAs into the array's ring of recent DOAs; the unclaimed ones wait to seed tracks.
  void remember(const Frame& frame);
  bool try_initiate(int array, std::size_t recent_index, double time_s);
  // Seeds older than fed_time_s - kInitiationDelayS: every array's DOAs of their moment are in
  // the rings, so the pairing can prefer the point more arrays agree with.
  void initiate_pending();
  std::vector<PendingSeed> pending_seeds;
  // Issue 15: DOAs still unclaimed init_pair_window_s after their time (no second array paired
  // them) start a track from their array alone.
  std::vector<PendingSeed> pending_single_seeds;
  bool try_start_one_array(int array, std::size_t recent_index, double time_s);
  // A one-array track whose hypotheses have collapsed to one and that a second array now hears is
  // handed to the default filter.
  void hand_over(Track& track);
  // A one-array track that a second array's DOA (a ray) now hears: the track's bearing from its
  // first array and that ray are triangulated, and the default filter starts at the fix (same
  // id). False when they do not cross in front of both.
  bool hand_over_by_triangulation(Track& track, const doa::DoaMeasurement& m,
                                  const DoaMeasurementModel& model, double time_s) {
    return refix_by_triangulation(track, track.origin_array, track.origin_noise, m, model, time_s);
  }
  // The same for any track whose position spread lies along the ray of the one array that kept
  // hearing it (spared by lost()): its bearing from that array and the second array's ray.
  bool refix_by_triangulation(Track& track, int origin_array,
                              const MeasurementCovariance& origin_noise,
                              const doa::DoaMeasurement& m, const DoaMeasurementModel& model,
                              double time_s);
  int last_array(const Track& track) const;  // the array that updated it last, -1 if none
  // The array whose ray a track's position spread lies along when that spread exceeds
  // max_position_std_m (a track only that array kept hearing, spared by lost()); -1 otherwise.
  int open_range_array(const Track& track) const {
    const double max_variance = params.max_position_std_m * params.max_position_std_m;
    const Eigen::Vector3d variance =
        track.filter->covariance().diagonal().segment<3>(StateBlock::position);
    if (variance.maxCoeff() <= max_variance) return -1;
    return last_array(track);
  }
  // The prior of a track started at a triangulated fix.
  void state_from_fix(const Triangulation& fix, const Eigen::Vector3d& centre_m,
                      double speed_of_sound_mps, StateVector& mean,
                      StateCovariance& covariance) const {
    // The fix is where the drone was when the sound left it, about r / c ago; an unknown velocity
    // over that delay widens the position.
    const double delay_s = (fix.position_m - centre_m).norm() / speed_of_sound_mps;
    mean = StateVector::Zero();
    mean.segment<3>(StateBlock::position) = fix.position_m;
    covariance = StateCovariance::Zero();
    const double velocity_var = std::pow(params.init_velocity_std_mps, 2);
    covariance.block<3, 3>(StateBlock::position, StateBlock::position) =
        fix.covariance_m2 + Eigen::Matrix3d::Identity() * (velocity_var * delay_s * delay_s + 0.01);
    covariance.block<3, 3>(StateBlock::velocity, StateBlock::velocity) =
        Eigen::Matrix3d::Identity() * velocity_var;
    covariance.block<3, 3>(StateBlock::acceleration, StateBlock::acceleration) =
        Eigen::Matrix3d::Identity() * std::pow(params.init_acceleration_std_mps2, 2);
  }
  double gate_for(int dimension) const { return dimension == 1 ? gate_chi2_1d : gate_chi2; }
  // The measurement model of one DOA: its array's, moved to the pose stamp's centre for a moving
  // array, of the kind its ambiguity says it measured.
  DoaMeasurementModel model_of(const doa::DoaMeasurement& m) const {
    DoaMeasurementModel model = models[static_cast<std::size_t>(m.array_index)];
    if (m.pose.moving) model.centre_m = m.pose.centre_m;
    switch (m.ambiguity) {
      case doa::DoaAmbiguity::none:
        break;
      case doa::DoaAmbiguity::cone:
        model.kind = MeasurementKind::cone;
        model.axis = m.ambiguity_axis.normalized();
        break;
      case doa::DoaAmbiguity::mirror_up_down:
        model.kind = MeasurementKind::mirrored_azel;
        model.axis = m.ambiguity_axis.normalized();
        model.mirror_side = m.direction.dot(model.axis) < 0.0 ? -1.0 : 1.0;
        break;
    }
    return model;
  }
  static Measurement measured(const doa::DoaMeasurement& m) {
    return m.ambiguity == doa::DoaAmbiguity::cone ? Measurement(m.cone_angle_rad, 0.0)
                                                  : azel_of(m.direction);
  }
  // The DOA's own covariance (a cone's pad slot 0: its unit variance is in floor_of).
  static MeasurementCovariance own_noise(const doa::DoaMeasurement& m) {
    if (m.ambiguity != doa::DoaAmbiguity::cone) return m.azel_covariance_rad2;
    MeasurementCovariance r = MeasurementCovariance::Zero();
    r(0, 0) = m.cone_angle_variance_rad2;
    return r;
  }
  // The noise floor times the correlation inflation, with a cone's unit pad (state.hpp).
  MeasurementCovariance floor_of(const doa::DoaMeasurement& m, double inflation) const {
    MeasurementCovariance floor =
        (MeasurementCovariance::Identity() * floor_variance_rad2) * inflation;
    if (m.ambiguity == doa::DoaAmbiguity::cone) floor(1, 1) = 1.0;
    return floor;
  }
  static MeasurementPeaks peaks_of(const doa::DoaMeasurement& m) {
    MeasurementPeaks peaks;
    if (m.ambiguity != doa::DoaAmbiguity::cone) return peaks;
    peaks.count = std::clamp(m.cone_peak_count, 0, doa::kMaxConePeaks);
    for (int k = 0; k < peaks.count; ++k) {
      peaks.value[static_cast<std::size_t>(k)] = {
          m.cone_peak_angle_rad[static_cast<std::size_t>(k)], 0.0};
      peaks.weight[static_cast<std::size_t>(k)] = m.cone_peak_weight[static_cast<std::size_t>(k)];
    }
    return peaks;
  }
  // A ground-reflection image: more than 3 sigma under the ground.
  bool below_ground(const Triangulation& fix) const {
    const double z_std = std::sqrt(std::max(fix.covariance_m2(2, 2), 0.0));
    return fix.position_m.z() + 3.0 * z_std < params.ground_altitude_m;
  }
  // Track life cycle. Confirmation and deletion are decided at each frame (deletion before the
  // frame's assignment, confirmation after it), so the tracks do not depend on how the caller
  // batches advance_to (replay from audio advances per audio block, --doa-in per DOA line);
  // life_cycle (at each advance) deletes up to that time and updates the classifier.
  void life_cycle(double now_s);
  void confirm_tracks(double now_s);
  // After each frame (at its time, so that the tracks do not depend on how the caller batches
  // advance_to): since when each track has been a duplicate along a sharper track's ray
  // (TrackConfirmation::duplicate_along_ray); delete_expired prunes it after kDuplicateDwellS.
  void mark_duplicates(double now_s);
  void delete_expired(double now_s);
  std::optional<TrackConfirmation> confirmation;  // the rules confirm_tracks applies
  // A position spread beyond max_position_std_m is a lost track, except along the ray of an array
  // that still hears it: one static array's bearings give no range, so a hovering drone only that
  // array hears keeps a spread along its ray that grows for as long as no second array hears it
  // (its range unknown, its direction held). Deleting it then re-births it under a new id when a
  // second array returns. Lost: no two arrays ever fixed its range (confirm_hits updates each),
  // that array no longer hearing it (M of N), its spread across that ray beyond the bound, or
  // three stds along it beyond its range (the UKF's sigma points would then lie behind the array).
  bool lost(const Track& track, double now_s) const;
  bool held_by_one_array(const Track& track) const {
    return fusion::held_by_one_array(track, arrays.size(), params.confirm_hits);
  }
  // The widest IMM jerk level's process noise over kManoeuvreSpanS, and its position variance.
  StateCovariance manoeuvre_noise = StateCovariance::Zero();
  double manoeuvre_position_variance_m2 = 0.0;
  // A track the frame gave no DOA: the frame's nearest DOA that no track took, beyond the gate,
  // against that array's previous one (kManoeuvreRunGapS); when both agree, the track is widened
  // by manoeuvre_noise and the DOA offered again. Returns the DOA's index when it was taken.
  int follow_manoeuvre(Track& track, int array, std::size_t begin, int doa_count, double time_s);
  // The bookkeeping of a DOA a track took, or one that started it: the one path by which a DOA's
  // spectrum reaches both the per-array tally (one spectrum at every array) and the classifier.
  void record_update(Track& track, int array, const doa::AcousticFeatures& acoustic,
                     double time_s) {
    track.hits_by_array[array] |= 1u;
    track.last_update_s = time_s;
    track.heard_by_array_s[array] = time_s;
    ++track.updates_by_array[array];
    track.acoustic_by_array[array].add(acoustic);
    classifier->add_acoustic(track.evidence, acoustic, time_s);
  }
  void note(FilterStatus status) {
    if (status == FilterStatus::repaired) ++counters.filter_repairs;
    if (status == FilterStatus::failed) ++counters.filter_failures;
  }
  MeasurementCovariance noise_of(const doa::DoaMeasurement& m) const {
    if (m.ambiguity == doa::DoaAmbiguity::cone) return own_noise(m) + floor_of(m, 1.0);
    return m.azel_covariance_rad2 + MeasurementCovariance::Identity() * floor_variance_rad2;
  }
  // Effective sample size: DOAs of one array closer together than the span their errors are
  // correlated over carry less than independent ones; scale their covariance by span / spacing.
  double correlation_inflation(const Track& track, int array, double time_s) const {
    const double since_s = time_s - track.heard_by_array_s[array];
    if (!(params.doa_error_correlation_s > 0.0) || !(since_s > 0.0)) return 1.0;
    return std::max(1.0, params.doa_error_correlation_s / since_s);
  }
};

}  // namespace dronetrack::fusion
