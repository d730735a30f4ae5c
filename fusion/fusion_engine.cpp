// The tracker: a reorder buffer feeding frames (one array, one time) oldest first into a short
// loop of small parts: predict every track to the frame time, gate, assign (Hungarian), update,
// initiate from unassigned DOAs by triangulation, then the life cycle (confirm, coast, delete).
#include "fusion/fusion_engine.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>

#include "common/log.hpp"
#include "fusion/assignment.hpp"
#include "fusion/doa_likelihood.hpp"
#include "fusion/gaussian_sum_filter.hpp"
#include "fusion/measurement_model.hpp"
#include "fusion/outlier_share.hpp"
#include "fusion/track_filter.hpp"
#include "fusion/triangulation.hpp"

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

namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;
constexpr int kMaxArrays = 64;               // contributing_arrays is a 64-bit mask
constexpr std::size_t kRecentPerArray = 64;  // recent DOAs kept per array for initiation
constexpr double kUnitTolerance = 1e-3;
constexpr double kNeverS = -std::numeric_limits<double>::infinity();
// A DOA heard by a track within this long counts in contributing_arrays.
constexpr double kContributionMemoryS = 1.0;
// A DOA no track took seeds a new one only once the DOAs of the next frames are in (a hop is
// 0.05 s): every array that heard that moment can then vote between the pairings.
constexpr double kInitiationDelayS = 0.06;
constexpr std::size_t kMaxPendingSeeds = 256;
// Manoeuvre onset (issue 17): a DOA beyond a track's gate is an outlier or the track falling
// behind a manoeuvre. Outliers are independent from frame to frame; a manoeuvre makes the
// array's next DOA agree with this one. Two consecutive such DOAs of one array (no more than
// kManoeuvreRunGapS apart) that agree with each other, within the reach of a manoeuvre of the
// widest IMM jerk level lasting kManoeuvreSpanS, widen the track by that manoeuvre's process noise.
constexpr double kManoeuvreRunGapS = 0.2;
constexpr double kManoeuvreSpanS = 0.5;
// Impulsive DOA errors (alpha-stable, a few degrees' scale) land mostly within this of the source.
constexpr double kBesideAngleRad = 20.0 * std::numbers::pi / 180.0;

void check(bool ok, const char* parameter, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("fusion.") + parameter + ": " + what);
}

// One recent DOA of one array, kept for initiation and ghost checks.
struct RecentDoa {
  double time_s = 0.0;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // a cone's is for display only
  DoaMeasurementModel model;                             // from its pose and ambiguity
  Measurement z = Measurement::Zero();
  MeasurementCovariance noise = MeasurementCovariance::Identity();  // R incl. floor
  bool associated = false;                                          // went to a track
  // The id of the tentative track one array alone keeps updating (held_by_one_array) that it
  // went to, else -1. That track's range is only what its first pair said, which may have been
  // a crossing with another source's ray: the DOA may still pair with another array's to start
  // a track, which then replaces that one.
  int weak_claimant_id = -1;
  bool used = false;               // started a track
  doa::AcousticFeatures acoustic;  // what its spectrum said (the track it starts tallies it)
  // Rays a triangulation may use: the direction, and its mirror image for a planar array. A
  // cone is no ray (its display direction is one point of a surface): 0.
  int image_count() const {
    switch (model.kind) {
      case MeasurementKind::azel:
        return 1;
      case MeasurementKind::mirrored_azel:
        return 2;
      case MeasurementKind::cone:
        return 0;
    }
    return 0;
  }
  Eigen::Vector3d image(int index) const {
    return index == 0 ? direction
                      : Eigen::Vector3d(direction - 2.0 * direction.dot(model.axis) * model.axis);
  }
};

class RecentRing {
 public:
  // Returns the entry's sequence number (find() takes it back while the entry is kept).
  std::uint64_t push(const RecentDoa& doa) {
    items_[(start_ + size_) % kRecentPerArray] = doa;
    if (size_ < kRecentPerArray) {
      ++size_;
    } else {
      start_ = (start_ + 1) % kRecentPerArray;
      ++first_sequence_;
    }
    return first_sequence_ + size_ - 1;
  }
  // The index of the entry pushed as `sequence`, if it is still kept.
  std::optional<std::size_t> find(std::uint64_t sequence) const {
    if (sequence < first_sequence_ || sequence >= first_sequence_ + size_) return std::nullopt;
    return static_cast<std::size_t>(sequence - first_sequence_);
  }
  // Drops entries older than `oldest_s`; returns how many left never associated nor used.
  int expire(double oldest_s) {
    int unclaimed = 0;
    while (size_ > 0 && items_[start_].time_s < oldest_s) {
      if (!items_[start_].associated && !items_[start_].used) ++unclaimed;
      start_ = (start_ + 1) % kRecentPerArray;
      --size_;
      ++first_sequence_;
    }
    return unclaimed;
  }
  std::size_t size() const { return size_; }
  RecentDoa& operator[](std::size_t i) { return items_[(start_ + i) % kRecentPerArray]; }
  RecentDoa& back() { return (*this)[size_ - 1]; }

 private:
  std::array<RecentDoa, kRecentPerArray> items_{};
  std::size_t start_ = 0;
  std::size_t size_ = 0;
  std::uint64_t first_sequence_ = 0;  // sequence number of the entry at start_
};

// What one array's DOAs taken by a track said of the source's spectrum (issue 14's ghosts): one
// source has one spectrum at every array, so two arrays hearing different spectra on one track
// are two sources whose rays cross.
struct AcousticTally {
  int analysed = 0;                 // DOAs with features
  int with_comb = 0;                // of those, with a harmonic comb (any fundamental)
  double fundamental_sum_hz = 0.0;  // over those with a comb
  void add(const doa::AcousticFeatures& features) {
    if (!features.valid) return;
    ++analysed;
    if (features.fundamental_hz > 0.0) {
      ++with_comb;
      fundamental_sum_hz += features.fundamental_hz;
    }
  }
};

// An unclaimed DOA waiting to seed a track until the other arrays' DOAs of its moment are in.
struct PendingSeed {
  int array = 0;
  std::uint64_t sequence = 0;
  double time_s = 0.0;
};

struct Track {
  int id = 0;
  std::unique_ptr<TrackFilter> filter;
  double time_s = 0.0;         // the filter's state time
  double last_update_s = 0.0;  // last DOA it took
  // M-of-N history per array, newest frame of that array in bit 0. A drone is heard by a
  // subset of the arrays (the nearest, or the ones a louder drone does not mask), so the hits
  // are counted per track over the last N frames of each array: one stream of all arrays'
  // frames would count the frames of the arrays that cannot hear it as misses.
  std::array<std::uint32_t, kMaxArrays> hits_by_array{};
  bool confirmed = false;
  std::array<double, kMaxArrays> heard_by_array_s{};
  std::array<int, kMaxArrays> updates_by_array{};  // DOAs taken from each array
  Innovation innovation;                           // of the current frame
  bool innovation_ok = false;
  // The innovation's prediction as a unit vector (an azel frame's): where the sound now arriving
  // left the track, seen from the frame's array.
  Eigen::Vector3d predicted_direction = Eigen::Vector3d::UnitX();
  double inflation = 1.0;  // of this frame's DOA covariance (correlated errors)
  TrackEvidence evidence;  // drone or not
  std::array<AcousticTally, kMaxArrays> acoustic_by_array{};
  double confirmed_at_s = 0.0;
  // Started from one array's DOAs (issue 15) and not yet handed to the default filter: its
  // range rests on hypotheses or the platform's motion, not on a triangulation.
  bool one_array = false;
  int origin_array = -1;                                                   // its one array
  MeasurementCovariance origin_noise = MeasurementCovariance::Identity();  // of its first DOA
  int branches_left = -1;  // a Gaussian sum's locus branches (mirror sides) with weight left
  // DOAs it took (tentative) in frames that held no more DOAs than the confirmed tracks their
  // array hears: the slot of a confirmed track's DOA, which an outlier had taken.
  int crowded_updates = 0;
  // Manoeuvre onset: per array (bit set: valid), the last DOA beyond the gate that no track took
  // but a manoeuvre could explain, as its residual from the prediction, its R and its time.
  std::uint64_t unexplained_arrays = 0;
  std::array<double, kMaxArrays> unexplained_s{};
  std::array<Measurement, kMaxArrays> unexplained_residual{};
  std::array<MeasurementCovariance, kMaxArrays> unexplained_noise{};
};

// A one-array Gaussian-sum track whose count of live branches (the locus's mirror sides) changed:
// one debug line (seed 003's "mirror hypotheses gone", docs/replicas.md measures it by this).
void log_branches(Track& track, double time_s) {
  const auto* sum = dynamic_cast<const GaussianSumFilter*>(track.filter.get());
  if (sum == nullptr) return;
  int left = 0;
  for (int branch = 0; branch < 4; ++branch) left += sum->branch_weight(branch) > 0.0 ? 1 : 0;
  if (left == track.branches_left) return;
  const StateVector& x = sum->mean();
  log::debug("fusion: track ", track.id, " t ", time_s, " s: ", left, " branch(es) left",
             track.branches_left < 0 ? " at its first update, " : ", ", sum->hypothesis_count(),
             " hypotheses, mean (", x(0), ", ", x(1), ", ", x(2), ")");
  track.branches_left = left;
}

}  // namespace

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
  void process_frame(std::size_t begin, std::size_t end);
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
  void delete_expired(double now_s);
  // Ghost test (issue 14): from every array that supports it, the track lies along the ray of
  // another confirmed track, so those tracks already explain its DOAs (two drones' crossing rays).
  bool explained_by_other_tracks(const Track& track) const;
  int recent_arrays(const Track& track) const;  // arrays that updated it within the last second
  // Ghost test (issue 14): the arrays feeding the track hear different spectra (a harmonic comb
  // at one, none at another, or combs whose spacings no Doppler shift between the arrays
  // explains): the rays of two sources that cross, each source heard by one of the arrays.
  bool spectra_disagree(const Track& track) const;
  // A position spread beyond max_position_std_m is a lost track, except along the ray of an array
  // that still hears it: one static array's bearings give no range, so a hovering drone only that
  // array hears keeps a spread along its ray that grows for as long as no second array hears it
  // (its range unknown, its direction held). Deleting it then re-births it under a new id when a
  // second array returns. Lost: no two arrays ever fixed its range (confirm_hits updates each),
  // that array no longer hearing it (M of N), its spread across that ray beyond the bound, or
  // three stds along it beyond its range (the UKF's sigma points would then lie behind the array).
  bool lost(const Track& track, double now_s) const;
  // A tentative track (not a one-array track) that one array has updated confirm_hits times
  // while no other array updated it after its birth: nothing but its first pair ever said where
  // along that array's ray it is. Where the pair was one source's ray crossing another's (issue
  // 14: a drone's ray and a passing car's), it would otherwise hold that array's DOAs of the
  // drone for as long as they come and keep the drone's own pair from starting its track.
  bool held_by_one_array(const Track& track) const;
  // Echo test (issue 14): every array's rays to a source and to its ground mirror lie in the
  // vertical plane through both, so DOAs that mix the two (an echo the node could not remove)
  // meet on the vertical line through the source, below it. A track there, under a confirmed
  // track, is that mixture: not confirmed.
  bool beneath_another_track(const Track& track) const;
  // The widest IMM jerk level's process noise over kManoeuvreSpanS, and its position variance.
  StateCovariance manoeuvre_noise = StateCovariance::Zero();
  double manoeuvre_position_variance_m2 = 0.0;
  // A track the frame gave no DOA: the frame's nearest DOA that no track took, beyond the gate,
  // against that array's previous one (kManoeuvreRunGapS); when both agree, the track is widened
  // by manoeuvre_noise and the DOA offered again. Returns the DOA's index when it was taken.
  int follow_manoeuvre(Track& track, int array, std::size_t begin, int doa_count, double time_s);
  // The bookkeeping of a DOA a track took.
  void record_update(Track& track, int array, const doa::DoaMeasurement& m, double time_s) {
    track.hits_by_array[array] |= 1u;
    track.last_update_s = time_s;
    track.heard_by_array_s[array] = time_s;
    ++track.updates_by_array[array];
    track.acoustic_by_array[array].add(m.acoustic);
    classifier->add_acoustic(track.evidence, m.acoustic, time_s);
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

FusionEngine::FusionEngine(const FusionParams& params, std::vector<doa::ArrayGeometry> arrays,
                           double speed_of_sound_mps)
    : impl_(std::make_unique<Impl>()) {
  check(params.jerk_noise_std_mps3 > 0.0, "jerk_noise_std_mps3", "must be > 0");
  check(params.output_rate_hz > 0.0, "output_rate_hz", "must be > 0");
  check(params.reorder_window_s >= 0.0, "reorder_window_s", "must be >= 0");
  check(params.gate_probability > 0.0 && params.gate_probability < 1.0, "gate_probability",
        "must be in (0, 1)");
  check(params.confirm_window >= 1 && params.confirm_window <= 32, "confirm_window",
        "must be in [1, 32]");
  check(params.confirm_hits >= 1 && params.confirm_hits <= params.confirm_window, "confirm_hits",
        "must be in [1, confirm_window]");
  check(params.coast_timeout_s > 0.0, "coast_timeout_s", "must be > 0");
  check(params.coast_after_s > 0.0, "coast_after_s", "must be > 0");
  check(params.tentative_timeout_s > 0.0, "tentative_timeout_s", "must be > 0");
  check(params.ukf_alpha > 0.0, "ukf_alpha", "must be > 0");
  check(params.ukf_alpha * params.ukf_alpha * (kStateSize + params.ukf_kappa) > 0.0, "ukf_kappa",
        "alpha^2 (9 + kappa) must be > 0");
  check(params.particle_count >= 10, "particle_count", "must be >= 10");
  check(params.student_t_dof >= 1.0, "student_t_dof", "must be >= 1");
  check(params.outlier_probability >= 0.0 && params.outlier_probability < 1.0,
        "outlier_probability", "must be in [0, 1)");
  check(params.doa_noise_floor_deg >= 0.0, "doa_noise_floor_deg", "must be >= 0");
  check(params.init_pair_window_s > 0.0, "init_pair_window_s", "must be > 0");
  check(params.init_max_range_m > 0.0, "init_max_range_m", "must be > 0");
  check(params.init_max_speed_mps >= 0.0, "init_max_speed_mps", "must be >= 0");
  check(params.init_velocity_std_mps > 0.0, "init_velocity_std_mps", "must be > 0");
  check(params.init_acceleration_std_mps2 > 0.0, "init_acceleration_std_mps2", "must be > 0");
  check(params.max_tracks >= 1, "max_tracks", "must be >= 1");
  check(params.confirm_min_arrays >= 1, "confirm_min_arrays", "must be >= 1");
  check(params.max_position_std_m > 0.0, "max_position_std_m", "must be > 0");
  for (double level : params.imm_jerk_std_mps3) {
    check(level > 0.0 && std::isfinite(level), "imm_jerk_std_mps3", "levels must be > 0");
  }
  check(params.imm_sojourn_s > 0.0, "imm_sojourn_s", "must be > 0");
  for (double level : params.imm_turn_rate_std_radps2) {
    check(level > 0.0 && std::isfinite(level), "imm_turn_rate_std_radps2", "levels must be > 0");
  }
  check(params.imm_turn_jerk_std_mps3 > 0.0 && std::isfinite(params.imm_turn_jerk_std_mps3),
        "imm_turn_jerk_std_mps3", "must be > 0");
  check(params.doa_error_correlation_s >= 0.0, "doa_error_correlation_s", "must be >= 0");
  check(std::isfinite(params.ground_altitude_m), "ground_altitude_m", "must be finite");
  if (!(speed_of_sound_mps > 0.0) || !std::isfinite(speed_of_sound_mps)) {
    throw std::invalid_argument("speed_of_sound_mps: must be a positive number");
  }
  const OneArrayParams& one = params.single_array;
  check(one.hypothesis_spacing_m > 0.0, "single_array.hypothesis_spacing_m", "must be > 0");
  check(one.hypotheses_per_side >= 1 && one.hypotheses_per_side <= 64,
        "single_array.hypotheses_per_side", "must be in [1, 64]");
  check(one.max_range_m > 0.0, "single_array.max_range_m", "must be > 0");
  check(one.hypothesis_range_ratio >= 1.0 && one.hypothesis_range_ratio <= 4.0,
        "single_array.hypothesis_range_ratio", "must be in [1, 4]");
  check(one.prune_gamma > 0.0 && one.prune_gamma < 1.0, "single_array.prune_gamma",
        "must be in (0, 1)");
  check(one.merge_d2 >= 0.0, "single_array.merge_d2", "must be >= 0");
  check(one.range_init_m > 0.0, "single_array.range_init_m", "must be > 0");
  check(one.range_init_std_m > 0.0, "single_array.range_init_std_m", "must be > 0");
  check(one.bearing_init_std_deg > 0.0, "single_array.bearing_init_std_deg", "must be > 0");
  check(one.jerk_std_mps3 > 0.0, "single_array.jerk_std_mps3", "must be > 0");
  check(one.velocity_std_mps > 0.0, "single_array.velocity_std_mps", "must be > 0");
  check(one.acceleration_std_mps2 > 0.0, "single_array.acceleration_std_mps2", "must be > 0");
  check(one.particle_count >= 10, "single_array.particle_count", "must be >= 10");
  check(!one.source_plane_z_m || std::isfinite(*one.source_plane_z_m), "source_plane_z_m",
        "must be finite");
  check(one.source_plane_std_m > 0.0, "source_plane_std_m", "must be > 0");
  const std::size_t min_arrays = params.single_array_start ? 1 : 2;
  if (arrays.size() < min_arrays || arrays.size() > static_cast<std::size_t>(kMaxArrays)) {
    throw std::invalid_argument(
        "arrays: fusion needs 2 to 64 arrays (1 with single_array_start), got " +
        std::to_string(arrays.size()));
  }
  Impl& s = *impl_;
  s.params = params;
  s.arrays = std::move(arrays);
  for (const auto& array : s.arrays) {
    s.models.push_back(
        {array.centre_site_m(), speed_of_sound_mps, params.model_propagation_delay ? 3 : 0});
  }
  s.filter_settings.motion.jerk_variance_m2ps6 =
      params.jerk_noise_std_mps3 * params.jerk_noise_std_mps3;
  s.filter_settings.ukf_alpha = params.ukf_alpha;
  s.filter_settings.ukf_beta = params.ukf_beta;
  s.filter_settings.ukf_kappa = params.ukf_kappa;
  s.filter_settings.particle_count = params.particle_count;
  s.likelihood.emplace(params.likelihood, params.student_t_dof, params.outlier_probability,
                       params.gate_probability);
  s.filter_settings.likelihood = *s.likelihood;
  s.filter_settings.imm_jerk_std_mps3 = params.imm_jerk_std_mps3;
  if (params.imm_jerk_std_mps3.size() == 1) {  // one level: a single model at that level
    s.filter_settings.motion.jerk_variance_m2ps6 = std::pow(params.imm_jerk_std_mps3[0], 2);
  }
  s.filter_settings.imm_sojourn_s = params.imm_sojourn_s;
  if (params.imm_turn_mode) {
    s.filter_settings.imm_turn_rate_std_radps2 = params.imm_turn_rate_std_radps2;
  }
  s.filter_settings.imm_turn_jerk_std_mps3 = params.imm_turn_jerk_std_mps3;
  s.classifier.emplace(params.classifier, params.ground_altitude_m);
  s.gate_chi2 = chi_square_quantile(params.gate_probability, 2);
  s.gate_chi2_1d = chi_square_quantile(params.gate_probability, 1);
  // The one-array localisers run one constant-jerk model (static and slow sources) with their own
  // prior, particle count and the source plane.
  s.one_array_settings = s.filter_settings;
  s.one_array_settings.imm_jerk_std_mps3.clear();
  s.one_array_settings.imm_turn_rate_std_radps2.clear();
  s.one_array_settings.motion_kind = MotionKind::constant_jerk;
  s.one_array_settings.motion.jerk_variance_m2ps6 = one.jerk_std_mps3 * one.jerk_std_mps3;
  s.one_array_settings.particle_count = one.particle_count;
  s.one_array_settings.one_array = one;
  // No track is placed farther from every array than init_max_range_m: nor a hypothesis.
  s.one_array_settings.one_array.max_range_m = std::min(one.max_range_m, params.init_max_range_m);
  s.one_array_settings.one_array.max_speed_mps = params.init_max_speed_mps;
  for (const auto& model : s.models) s.last_centre_m.push_back(model.centre_m);
  s.floor_variance_rad2 = std::pow(params.doa_noise_floor_deg * kRadPerDeg, 2);
  {
    double widest_jerk = params.jerk_noise_std_mps3;
    for (double level : params.imm_jerk_std_mps3) widest_jerk = std::max(widest_jerk, level);
    ConstantJerkModel manoeuvre;
    manoeuvre.jerk_variance_m2ps6 = widest_jerk * widest_jerk;
    s.manoeuvre_noise = manoeuvre.process_noise(kManoeuvreSpanS);
    s.manoeuvre_position_variance_m2 = s.manoeuvre_noise(0, 0);
  }
  s.last_fed_time_by_array.assign(s.arrays.size(), kNeverS);
  s.last_fed_sources_by_array.assign(s.arrays.size(), 0);
  s.recent.resize(s.arrays.size());
  s.queue.reserve(1024);
  for (std::size_t a = 0; a < s.arrays.size(); ++a)
    s.mirror_checks.emplace_back(static_cast<int>(a), s.arrays[a], params.mirror_check);
  if (params.likelihood == DoaLikelihoodKind::outlier_mixture &&
      params.adaptive_outlier_probability) {
    s.outlier_shares.reserve(s.arrays.size());
    for (std::size_t a = 0; a < s.arrays.size(); ++a)
      s.outlier_shares.emplace_back(params.outlier_probability, params.outlier_prior_doas,
                                    params.outlier_window_doas);
  }
  s.references.reserve(static_cast<std::size_t>(params.max_tracks));
  s.mirror_events.reserve(16);
  s.pending_seeds.reserve(kMaxPendingSeeds);
  s.pending_single_seeds.reserve(kMaxPendingSeeds);
  s.tracks.reserve(static_cast<std::size_t>(params.max_tracks));
}

FusionEngine::~FusionEngine() = default;
FusionEngine::FusionEngine(FusionEngine&&) noexcept = default;
FusionEngine& FusionEngine::operator=(FusionEngine&&) noexcept = default;

namespace {
// The checks of a DOA that need no tracker state; `index` gets its array's index in `arrays`.
DoaVerdict check_measurement(const doa::DoaMeasurement& measurement,
                             const std::vector<doa::ArrayGeometry>& arrays, int& index) {
  const bool cone = measurement.ambiguity == doa::DoaAmbiguity::cone;
  if (!std::isfinite(measurement.time_s) || !measurement.direction.allFinite() ||
      (!cone && !measurement.azel_covariance_rad2.allFinite()) ||
      (measurement.pose.moving && !measurement.pose.centre_m.allFinite()) ||
      (measurement.ambiguity != doa::DoaAmbiguity::none &&
       !measurement.ambiguity_axis.allFinite()) ||
      (cone && !(std::isfinite(measurement.cone_angle_rad) &&
                 std::isfinite(measurement.cone_angle_variance_rad2)))) {
    return DoaVerdict::non_finite;
  }
  // The index is trusted only when it agrees with the id (or the id is absent).
  index = measurement.array_index;
  const auto count = static_cast<int>(arrays.size());
  const bool index_ok = index >= 0 && index < count &&
                        (measurement.array_id.empty() || arrays[index].id == measurement.array_id);
  if (!index_ok) {
    index = -1;
    for (int i = 0; i < count; ++i) {
      if (!measurement.array_id.empty() && arrays[i].id == measurement.array_id) index = i;
    }
    if (index < 0) return DoaVerdict::unknown_array;
  }
  if (std::abs(measurement.direction.norm() - 1.0) > kUnitTolerance) {
    return DoaVerdict::bad_direction;
  }
  if (measurement.ambiguity != doa::DoaAmbiguity::none &&
      std::abs(measurement.ambiguity_axis.norm() - 1.0) > kUnitTolerance) {
    return DoaVerdict::bad_direction;
  }
  if (cone) {
    // The cone is the measurement (its display direction is not): an angle in [0, pi] with a
    // positive variance.
    if (!(measurement.cone_angle_rad >= 0.0 && measurement.cone_angle_rad <= std::numbers::pi) ||
        !(measurement.cone_angle_variance_rad2 > 0.0)) {
      return DoaVerdict::bad_direction;
    }
  } else {
    const MeasurementCovariance& r = measurement.azel_covariance_rad2;
    if (!(r(0, 0) > 0.0) || !(r.determinant() > 0.0) ||
        std::abs(r(0, 1) - r(1, 0)) > 1e-12 * r.norm()) {
      return DoaVerdict::bad_direction;
    }
  }
  if (measurement.source_index < 0 || measurement.source_index >= 64) {
    return DoaVerdict::bad_direction;
  }
  return DoaVerdict::accepted;
}

DoaVerdict count_verdict(FusionCounters& counters, DoaVerdict verdict) {
  // In the enum's order; accepted is counted where the DOA is taken.
  static_assert(static_cast<int>(DoaVerdict::bad_direction) == 5);
  std::int64_t* const rejected[] = {nullptr,
                                    &counters.rejected_non_finite,
                                    &counters.rejected_unknown_array,
                                    &counters.rejected_too_late,
                                    &counters.rejected_duplicate,
                                    &counters.rejected_bad_direction};
  if (std::int64_t* counter = rejected[static_cast<std::size_t>(verdict)]) ++*counter;
  return verdict;
}
}  // namespace

DoaVerdict FusionEngine::admit(const doa::DoaMeasurement& measurement) {
  int index = -1;
  const DoaVerdict verdict = check_measurement(measurement, impl_->arrays, index);
  if (verdict == DoaVerdict::accepted) ++impl_->counters.accepted;
  return count_verdict(impl_->counters, verdict);
}

DoaVerdict FusionEngine::add(const doa::DoaMeasurement& measurement) {
  Impl& s = *impl_;
  auto reject = [&s](DoaVerdict verdict) { return count_verdict(s.counters, verdict); };
  int index = -1;
  if (const DoaVerdict verdict = check_measurement(measurement, s.arrays, index);
      verdict != DoaVerdict::accepted)
    return reject(verdict);
  if (measurement.time_s < s.fed_time_s) return reject(DoaVerdict::too_late);
  const std::uint64_t source_bit = std::uint64_t{1} << measurement.source_index;
  if (measurement.time_s == s.last_fed_time_by_array[index] &&
      (s.last_fed_sources_by_array[index] & source_bit) != 0) {
    return reject(DoaVerdict::duplicate);
  }
  const auto key = [](const doa::DoaMeasurement& m) {
    return std::make_tuple(m.time_s, m.array_index, m.source_index);
  };
  doa::DoaMeasurement queued = measurement;
  queued.array_index = index;
  queued.direction.normalize();
  const auto position =
      std::upper_bound(s.queue.begin(), s.queue.end(), queued,
                       [&key](const doa::DoaMeasurement& a, const doa::DoaMeasurement& b) {
                         return key(a) < key(b);
                       });
  if (position != s.queue.begin() && key(*(position - 1)) == key(queued)) {
    return reject(DoaVerdict::duplicate);
  }
  s.queue.insert(position, std::move(queued));
  ++s.counters.accepted;
  return DoaVerdict::accepted;
}

void FusionEngine::advance_to(double time_s) {
  if (!std::isfinite(time_s)) return;
  impl_->feed_until(time_s - impl_->params.reorder_window_s);
}

void FusionEngine::Impl::feed_until(double cutoff_s) {
  std::size_t begin = 0;
  while (begin < queue.size() && queue[begin].time_s <= cutoff_s) {
    std::size_t end = begin + 1;
    while (end < queue.size() && queue[end].time_s == queue[begin].time_s &&
           queue[end].array_index == queue[begin].array_index) {
      ++end;
    }
    const double frame_time_s = queue[begin].time_s;
    delete_expired(frame_time_s);
    process_frame(begin, end);
    confirm_tracks(frame_time_s);
    begin = end;
  }
  queue.erase(queue.begin(), queue.begin() + static_cast<std::ptrdiff_t>(begin));
  if (cutoff_s > fed_time_s) life_cycle(cutoff_s);
}

void FusionEngine::Impl::process_frame(std::size_t begin, std::size_t end) {
  const int array = queue[begin].array_index;
  const double time_s = queue[begin].time_s;
  const auto doa_count = static_cast<int>(end - begin);
  fed_time_s = std::max(fed_time_s, time_s);
  if (last_fed_time_by_array[array] != time_s) last_fed_sources_by_array[array] = 0;
  last_fed_time_by_array[array] = time_s;
  for (std::size_t i = begin; i < end; ++i) {
    last_fed_sources_by_array[array] |= std::uint64_t{1} << queue[i].source_index;
  }
  // Every DOA of a frame shares its array's pose; a DOA of another ambiguity kind than the
  // frame's first (not expected from one array) is kept out of the assignment.
  frame_model = model_of(queue[begin]);
  const DoaMeasurementModel& model = frame_model;
  last_centre_m[static_cast<std::size_t>(array)] = model.centre_m;
  const int dimension = model.dimension();
  const doa::DoaAmbiguity frame_ambiguity = queue[begin].ambiguity;
  // The array's e as it stood before this frame: gate, cost and update alike.
  OutlierShareEstimate* const outlier_share =
      outlier_shares.empty() ? nullptr : &outlier_shares[static_cast<std::size_t>(array)];
  const std::optional<double> share =
      outlier_share ? std::optional<double>(outlier_share->share()) : std::nullopt;

  // Predict and gate: cost = d^2 + ln det S (the negative log-likelihood up to a constant), so a
  // vague track does not steal DOAs from a sharp one.
  const auto track_count = static_cast<int>(tracks.size());
  cost.assign(static_cast<std::size_t>(track_count) * doa_count, kForbidden);
  distance2.assign(cost.size(), std::numeric_limits<double>::infinity());
  for (int t = 0; t < track_count; ++t) {
    Track& track = tracks[t];
    track.filter->predict(time_s - track.time_s);
    track.time_s = time_s;
    track.inflation = correlation_inflation(track, array, time_s);
    const FilterStatus status =
        track.filter->innovation(model, floor_of(queue[begin], track.inflation), track.innovation);
    note(status);
    track.innovation_ok = status != FilterStatus::failed;
    if (!track.innovation_ok) continue;
    const Measurement& azel = track.innovation.predicted;
    track.predicted_direction =
        doa::direction_from_azel_deg(azel(0) / kRadPerDeg, azel(1) / kRadPerDeg);
    for (int j = 0; j < doa_count; ++j) {
      const doa::DoaMeasurement& m = queue[begin + j];
      if (m.ambiguity != frame_ambiguity) continue;
      Innovation candidate = track.innovation;
      candidate.covariance += track.inflation * own_noise(m);
      const double d2 = candidate.mahalanobis2(measured(m));
      distance2[static_cast<std::size_t>(t) * doa_count + j] = d2;
      if (d2 <= likelihood->gate_d2(dimension)) {
        cost[static_cast<std::size_t>(t) * doa_count + j] = likelihood->assignment_cost(
            d2, std::log(candidate.covariance.determinant()), dimension, share);
      }
    }
  }
  check_mirror(array, begin, end, time_s);
  assignment.solve(cost, track_count, doa_count, track_to_doa);

  doa_taken.assign(static_cast<std::size_t>(doa_count), 0);
  doa_confirmed.assign(static_cast<std::size_t>(doa_count), 0);
  for (int t = 0; t < track_count; ++t) {
    if (tracks[t].confirmed && track_to_doa[t] >= 0)
      doa_confirmed[static_cast<std::size_t>(track_to_doa[t])] = 1;
  }
  weak_claimant.assign(static_cast<std::size_t>(doa_count), -1);
  int confirmed_heard = 0;  // confirmed tracks this array hears
  for (const Track& track : tracks) {
    if (track.confirmed && time_s - track.heard_by_array_s[array] <= kContributionMemoryS)
      ++confirmed_heard;
  }
  const bool crowded = doa_count <= confirmed_heard;
  // A confirmed track this array hears that got no DOA from this frame, within kBesideAngleRad
  // of `direction`: an impulsive error of its source (reflection, gust) lands around it.
  const auto beside_missed_track = [&](const Eigen::Vector3d& direction) {
    for (int t = 0; t < track_count; ++t) {
      const Track& other = tracks[t];
      if (!other.confirmed || track_to_doa[t] >= 0 || !other.innovation_ok ||
          time_s - other.heard_by_array_s[array] > kContributionMemoryS)
        continue;
      if (other.predicted_direction.dot(direction) >= beside_cosine) return true;
    }
    return false;
  };
  for (int t = 0; t < track_count; ++t) {
    Track& track = tracks[t];
    track.hits_by_array[array] <<= 1;
    const int j = track_to_doa[t];
    if (j < 0) continue;
    const doa::DoaMeasurement& m = queue[begin + j];
    const int single = track.one_array ? track.origin_array : open_range_array(track);
    if (single >= 0 && array != single &&
        refix_by_triangulation(track, single,
                               track.one_array ? track.origin_noise : floor_of(m, 1.0), m, model,
                               time_s)) {
      doa_taken[j] = 1;
      record_update(track, array, m, time_s);
      continue;
    }
    Innovation innovation = track.innovation;
    innovation.covariance += track.inflation * own_noise(m);
    innovation.noise = track.inflation * noise_of(m);
    if (m.ambiguity == doa::DoaAmbiguity::cone) innovation.noise(1, 1) = 1.0;  // the pad
    innovation.outlier_probability = share;
    const Measurement z = measured(m);
    // A confirmed track's gated DOAs inform the array's e (another source's DOA in the gate is an
    // outlier for this track, which is what e models). A tentative track may be a ghost, whose
    // "inliers" are nobody's.
    if (outlier_share && track.confirmed) {
      outlier_share->add(likelihood->outlier_density_ratio(
          distance2[static_cast<std::size_t>(t) * doa_count + j], dimension));
    }
    // The filter weighs z by the DOA likelihood itself (FilterSettings::likelihood).
    const FilterStatus status = track.filter->update_with_peaks(innovation, z, peaks_of(m));
    note(status);
    doa_taken[j] = 1;  // gated to a live track: never an initiation seed, even if refused
    if (held_by_one_array(track)) weak_claimant[j] = track.id;
    if (status == FilterStatus::failed) continue;
    record_update(track, array, m, time_s);
    if (crowded && !track.confirmed && beside_missed_track(m.direction)) ++track.crowded_updates;
    if (track.one_array) {
      if (log::level() <= log::Level::debug) log_branches(track, time_s);
      hand_over(track);
    }
  }

  for (int t = 0; t < track_count; ++t) {
    const std::uint64_t bit = std::uint64_t{1} << array;
    Track& track = tracks[t];
    if (track_to_doa[t] >= 0 || !track.confirmed || track.one_array || !track.innovation_ok ||
        dimension != 2) {
      track.unexplained_arrays &= ~bit;
      continue;
    }
    const int j = follow_manoeuvre(track, array, begin, doa_count, time_s);
    if (j >= 0)
      doa_taken[static_cast<std::size_t>(j)] = doa_confirmed[static_cast<std::size_t>(j)] = 1;
  }

  if (outlier_share) outlier_share->refresh();

  // Unassigned DOAs: remember them, and try to start a track with other arrays' recent DOAs.
  RecentRing& ring = recent[array];
  counters.gated_out += ring.expire(time_s - 2.0 * params.init_pair_window_s);
  for (int j = 0; j < doa_count; ++j) {
    const doa::DoaMeasurement& m = queue[begin + j];
    RecentDoa entry;
    entry.time_s = time_s;
    entry.direction = m.direction;
    entry.model = model_of(m);
    entry.z = measured(m);
    entry.noise = noise_of(m);
    entry.associated = doa_taken[j] != 0;
    entry.weak_claimant_id = weak_claimant[j];
    entry.acoustic = m.acoustic;
    const std::uint64_t sequence = ring.push(entry);
    if (!entry.associated && entry.image_count() > 0 && pending_seeds.size() < kMaxPendingSeeds)
      pending_seeds.push_back({array, sequence, time_s});
    if (!entry.associated && params.single_array_start &&
        pending_single_seeds.size() < kMaxPendingSeeds)
      pending_single_seeds.push_back({array, sequence, time_s});
  }
  initiate_pending();
}

int FusionEngine::Impl::follow_manoeuvre(Track& track, int array, std::size_t begin, int doa_count,
                                         double time_s) {
  const std::uint64_t bit = std::uint64_t{1} << array;
  int nearest = -1;
  double nearest_d2 = std::numeric_limits<double>::infinity();
  Measurement residual = Measurement::Zero();
  MeasurementCovariance covariance = MeasurementCovariance::Identity();
  for (int j = 0; j < doa_count; ++j) {
    const doa::DoaMeasurement& m = queue[begin + static_cast<std::size_t>(j)];
    // A DOA a tentative track took is no evidence against a manoeuvre: where the confirmed track
    // falls behind, a young track along the array's ray (an outlier pair's) gates it first.
    if (doa_confirmed[static_cast<std::size_t>(j)] != 0 || m.ambiguity != doa::DoaAmbiguity::none)
      continue;
    Innovation candidate = track.innovation;
    candidate.covariance += track.inflation * own_noise(m);
    const Measurement r = candidate.residual(measured(m));
    const double d2 = r.dot(candidate.covariance.ldlt().solve(r));
    if (d2 < nearest_d2) {
      nearest = j;
      nearest_d2 = d2;
      residual = r;
      covariance = candidate.covariance;
    }
  }
  // Within the gate yet untaken: refused by the filter, nothing to judge.
  if (nearest < 0 || nearest_d2 <= likelihood->gate_d2(2)) {
    track.unexplained_arrays &= ~bit;
    return -1;
  }
  // Within a manoeuvre's reach: the position spread it builds, seen from the array (an azimuth
  // step is 1 / cos(elevation) wider).
  const Eigen::Vector3d centre = frame_model.centre_m;
  const double range_m = std::max((position_of(track.filter->mean()) - centre).norm(), 1.0);
  const double reach_rad2 = manoeuvre_position_variance_m2 / (range_m * range_m);
  const double cos_elevation = std::max(std::cos(track.innovation.predicted(1)), 0.05);
  MeasurementCovariance reach = covariance;
  reach(0, 0) += reach_rad2 / (cos_elevation * cos_elevation);
  reach(1, 1) += reach_rad2;
  if (residual.dot(reach.ldlt().solve(residual)) > likelihood->gate_d2(2)) {
    track.unexplained_arrays &= ~bit;
    return -1;
  }
  const doa::DoaMeasurement& m = queue[begin + static_cast<std::size_t>(nearest)];
  const MeasurementCovariance noise = noise_of(m);
  const auto a = static_cast<std::size_t>(array);
  bool agrees = false;
  if ((track.unexplained_arrays & bit) != 0 &&
      time_s - track.unexplained_s[a] <= kManoeuvreRunGapS) {
    const Measurement step = residual - track.unexplained_residual[a];
    agrees =
        step.dot((noise + track.unexplained_noise[a]).ldlt().solve(step)) <= likelihood->gate_d2(2);
  }
  track.unexplained_arrays |= bit;
  track.unexplained_s[a] = time_s;
  track.unexplained_residual[a] = residual;
  track.unexplained_noise[a] = noise;
  if (!agrees || !track.filter->add_process_noise(manoeuvre_noise)) return -1;
  ++counters.manoeuvres_followed;
  track.unexplained_arrays &= ~bit;
  const FilterStatus status =
      track.filter->innovation(frame_model, floor_of(m, track.inflation), track.innovation);
  note(status);
  if (status == FilterStatus::failed) return -1;
  Innovation innovation = track.innovation;
  innovation.covariance += track.inflation * own_noise(m);
  innovation.noise = track.inflation * noise;
  const Measurement z = measured(m);
  if (innovation.mahalanobis2(z) > likelihood->gate_d2(2)) return -1;
  const FilterStatus update_status = track.filter->update(innovation, z);
  note(update_status);
  if (update_status == FilterStatus::failed) return -1;
  record_update(track, array, m, time_s);
  return nearest;
}

void FusionEngine::Impl::check_mirror(int array, std::size_t begin, std::size_t end,
                                      double time_s) {
  ArrayMirrorCheck& check = mirror_checks[static_cast<std::size_t>(array)];
  const MirrorCheckSettings& settings = params.mirror_check;
  if (!settings.enabled || check.mirrors() == 0 || frame_model.kind != MeasurementKind::azel)
    return;
  references.clear();
  const double max_angle_rad = settings.max_track_angle_deg * kRadPerDeg;
  for (const Track& track : tracks) {
    if (!track.confirmed || !track.innovation_ok) continue;
    int others = 0;
    for (std::size_t a = 0; a < arrays.size(); ++a) {
      if (static_cast<int>(a) != array &&
          time_s - track.heard_by_array_s[a] <= kContributionMemoryS)
        ++others;
    }
    if (others < settings.min_other_arrays) continue;
    const Eigen::Vector3d offset_m = position_of(track.filter->mean()) - frame_model.centre_m;
    const double range_m = offset_m.norm();
    if (!(range_m > 0.0)) continue;
    // Only the spread across the judged array's ray turns its direction; the spread along the
    // ray (the other arrays' range error) does not, so it must not keep a track out.
    const Eigen::Matrix3d position_covariance = track.filter->covariance().topLeftCorner<3, 3>();
    const Eigen::Vector3d ray = offset_m / range_m;
    const double across_m2 =
        0.5 * (position_covariance.trace() - ray.dot(position_covariance * ray));
    if (!(std::sqrt(std::max(across_m2, 0.0)) <= max_angle_rad * range_m)) continue;
    references.push_back(track.predicted_direction);
  }
  if (references.empty()) return;
  const doa::PoseStamp& pose = queue[begin].pose;
  const Eigen::Matrix3d attitude = pose.moving
                                       ? pose.array_to_site.toRotationMatrix()
                                       : arrays[static_cast<std::size_t>(array)].array_to_site();
  for (std::size_t i = begin; i < end; ++i) {
    if (queue[i].ambiguity != doa::DoaAmbiguity::none) continue;
    check.observe(time_s, queue[i].direction, attitude, references);
  }
  for (const MirrorSwapEvent& event : check.events()) mirror_events.push_back(event);
  check.clear_events();
}

void FusionEngine::take_mirror_events(std::vector<MirrorSwapEvent>& out) {
  out.insert(out.end(), impl_->mirror_events.begin(), impl_->mirror_events.end());
  impl_->mirror_events.clear();
}

const MirrorCheckStatus& FusionEngine::mirror_status(std::size_t array) const {
  return impl_->mirror_checks.at(array).status();
}

double FusionEngine::outlier_share(std::size_t array) const {
  const Impl& s = *impl_;
  if (!s.outlier_shares.empty()) return s.outlier_shares.at(array).share();
  return s.params.likelihood == DoaLikelihoodKind::outlier_mixture ? s.params.outlier_probability
                                                                   : 0.0;
}

void FusionEngine::Impl::initiate_pending() {
  // Two arrays: no third to vote, nothing to wait for.
  const double delay_s = arrays.size() > 2 ? kInitiationDelayS : 0.0;
  std::size_t kept = 0;
  for (const PendingSeed& seed : pending_seeds) {
    if (seed.time_s > fed_time_s - delay_s) {
      pending_seeds[kept++] = seed;
      continue;
    }
    const auto index = recent[seed.array].find(seed.sequence);
    if (!index) continue;
    const RecentDoa& doa = recent[seed.array][*index];
    if (!doa.associated && !doa.used) try_initiate(seed.array, *index, seed.time_s);
  }
  pending_seeds.resize(kept);
  // Only once no second array could still pair it: the window the pairing looks across.
  kept = 0;
  for (const PendingSeed& seed : pending_single_seeds) {
    if (seed.time_s > fed_time_s - params.init_pair_window_s) {
      pending_single_seeds[kept++] = seed;
      continue;
    }
    const auto index = recent[seed.array].find(seed.sequence);
    if (!index) continue;
    const RecentDoa& doa = recent[seed.array][*index];
    if (!doa.associated && !doa.used) try_start_one_array(seed.array, *index, seed.time_s);
  }
  pending_single_seeds.resize(kept);
}

bool FusionEngine::Impl::try_initiate(int array, std::size_t recent_index, double time_s) {
  if (tracks.size() >= static_cast<std::size_t>(params.max_tracks)) return false;
  RecentDoa& seed = recent[array][recent_index];
  const auto array_count = static_cast<int>(arrays.size());
  // Rays of different arrays at nearby reception times left the drone at different emission
  // times (t - r / c); it moves up to init_max_speed_mps in between. Widen each ray's angular
  // noise by that motion seen from its range, relative to the seed's emission time.
  // A cone's 1-D residual leaves its pad slot at 0 (state.hpp): the same formula serves both.
  const auto chi2_against = [&](const RecentDoa& doa, int /*doa_array*/,
                                const Eigen::Vector3d& point, double reference_emission_s) {
    const Eigen::Vector3d to_point = point - doa.model.centre_m;
    const double range = std::max(to_point.norm(), 1.0);
    const double emission_s = doa.time_s - range / doa.model.speed_of_sound_mps;
    const double motion_m = params.init_max_speed_mps * std::abs(emission_s - reference_emission_s);
    const MeasurementCovariance r =
        doa.noise + MeasurementCovariance::Identity() * std::pow(motion_m / range, 2);
    const Measurement residual = doa.model.residual(doa.z, doa.model.predict_direction(to_point));
    return residual.dot(r.ldlt().solve(residual));
  };
  const Eigen::Vector3d seed_centre = seed.model.centre_m;
  const auto emission_of = [&](const Eigen::Vector3d& point) {
    return time_s - (point - seed_centre).norm() / models[array].speed_of_sound_mps;
  };

  // How many arrays other than the pair have an unclaimed recent DOA within the gate of `point`.
  const auto agreeing_arrays = [&](const Eigen::Vector3d& point, int first, int second) {
    int count = 0;
    for (int other = 0; other < array_count; ++other) {
      if (other == first || other == second) continue;
      RecentRing& ring = recent[other];
      for (std::size_t i = 0; i < ring.size(); ++i) {
        if (ring[i].used || ring[i].associated) continue;
        if (std::abs(time_s - ring[i].time_s) > params.init_pair_window_s) continue;
        if (chi2_against(ring[i], other, point, emission_of(point)) <=
            gate_for(ring[i].model.dimension())) {
          ++count;
          break;
        }
      }
    }
    return count;
  };
  struct Candidate {
    Triangulation fix;
    int partner_array = -1;
    std::size_t partner_index = 0;
    double score = std::numeric_limits<double>::infinity();
    int agreeing = -1;
    int seed_image = 0;
    int partner_image = 0;
  };
  Candidate best;
  // A planar array's DOA is two rays (it and its mirror image): each pairing tries both; a cone
  // is no ray and never pairs (its display direction is one point of a surface).
  for (int other = 0; other < array_count; ++other) {
    if (other == array) continue;
    RecentRing& ring = recent[other];
    for (std::size_t i = 0; i < ring.size(); ++i) {
      RecentDoa& partner = ring[i];
      if (partner.used || (partner.associated && partner.weak_claimant_id < 0)) continue;
      const double dt = std::abs(time_s - partner.time_s);
      if (dt > params.init_pair_window_s) continue;
      for (int seed_image = 0; seed_image < seed.image_count(); ++seed_image) {
        for (int partner_image = 0; partner_image < partner.image_count(); ++partner_image) {
          std::array<Ray, 2> pair{
              Ray{seed.model.centre_m, seed.image(seed_image), seed.noise},
              Ray{partner.model.centre_m, partner.image(partner_image), partner.noise}};
          const auto fix = triangulate(pair, params.triangulation);
          if (!fix || !fix->in_front) continue;
          const Eigen::Vector3d p = fix->position_m;
          if ((p - seed.model.centre_m).norm() > params.init_max_range_m) continue;
          if (below_ground(*fix)) {
            ++counters.below_ground_rejected;
            continue;
          }
          const double reference = emission_of(p);
          const double chi2 =
              chi2_against(seed, array, p, reference) + chi2_against(partner, other, p, reference);
          // Two rays, three unknowns: one degree of freedom left to test consistency.
          if (chi2 > chi_square_quantile(params.gate_probability, 1)) continue;
          // Where two drones' rays cross, the crossing fits its two rays as well as either drone
          // fits its own: prefer the point more of the other arrays agree with (issue 14's
          // ghosts).
          const int agreeing = agreeing_arrays(p, array, other);
          if (agreeing > best.agreeing || (agreeing == best.agreeing && chi2 < best.score))
            best = {*fix, other, i, chi2, agreeing, seed_image, partner_image};
        }
      }
    }
  }
  if (best.partner_array < 0) return false;

  // Other arrays' unclaimed DOAs that agree with the point sharpen the fix and count toward
  // the arrays that support the new track.
  rays.clear();
  rays.push_back({seed.model.centre_m, seed.image(best.seed_image), seed.noise});
  const RecentDoa& partner = recent[best.partner_array][best.partner_index];
  rays.push_back({partner.model.centre_m, partner.image(best.partner_image), partner.noise});
  std::array<int, kMaxArrays> extra_index{};
  extra_index.fill(-1);
  for (int other = 0; other < array_count; ++other) {
    if (other == array || other == best.partner_array) continue;
    RecentRing& ring = recent[other];
    bool heard = false;
    double best_chi2 = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const double dt = std::abs(time_s - ring[i].time_s);
      if (dt > params.init_pair_window_s) continue;
      heard = true;
      const double chi2 =
          chi2_against(ring[i], other, best.fix.position_m, emission_of(best.fix.position_m));
      if (chi2 < best_chi2) {
        best_chi2 = chi2;
        extra_index[other] = static_cast<int>(i);
      }
    }
    // No agreement is not proof of a ghost: with one or two DOAs per frame, a louder drone can
    // mask this one at that array. Continuity decides (confirm_min_arrays).
    if (!heard || extra_index[other] < 0 ||
        best_chi2 >
            gate_for(ring[static_cast<std::size_t>(extra_index[other])].model.dimension())) {
      extra_index[other] = -1;
      continue;
    }
    const RecentDoa& agreeing = ring[static_cast<std::size_t>(extra_index[other])];
    if (!agreeing.used && !agreeing.associated) {
      // A cone supports the point but is no ray; a planar array's image on the point's side is.
      if (agreeing.image_count() > 0) {
        const Eigen::Vector3d to_point = best.fix.position_m - agreeing.model.centre_m;
        const bool mirrored =
            agreeing.image_count() == 2 &&
            to_point.dot(agreeing.model.axis) * agreeing.direction.dot(agreeing.model.axis) < 0.0;
        rays.push_back({agreeing.model.centre_m, agreeing.image(mirrored ? 1 : 0), agreeing.noise});
      }
    } else {
      extra_index[other] = -1;
    }
  }
  Triangulation fix = best.fix;
  if (rays.size() > 2) {
    if (auto refined = triangulate_least_squares(rays)) fix = *refined;
  }

  if (below_ground(fix)) {  // the further arrays moved it under the ground
    ++counters.below_ground_rejected;
    return false;
  }

  // Not a new drone if an existing track already explains the point.
  for (const Track& track : tracks) {
    const Eigen::Vector3d difference = position_of(track.filter->mean()) - fix.position_m;
    const Eigen::Matrix3d spread =
        track.filter->covariance().topLeftCorner<3, 3>() + fix.covariance_m2;
    if (difference.dot(spread.ldlt().solve(difference)) < chi_square_quantile(0.999, 3)) {
      return false;
    }
  }

  StateVector mean;
  StateCovariance covariance;
  state_from_fix(fix, seed_centre, models[array].speed_of_sound_mps, mean, covariance);

  Track track;
  track.id = next_id++;
  FilterSettings settings = filter_settings;
  settings.random_seed = static_cast<std::uint64_t>(track.id);
  track.filter = make_track_filter(params.filter, settings);
  track.filter->initialise(mean, covariance);
  track.time_s = time_s;
  track.last_update_s = time_s;
  track.heard_by_array_s.fill(kNeverS);
  const auto seed_support = [&track, time_s](int supporting_array, const RecentDoa& doa) {
    track.hits_by_array[supporting_array] = 1u;
    track.heard_by_array_s[supporting_array] = time_s;
    track.updates_by_array[supporting_array] = 1;
    track.acoustic_by_array[supporting_array].add(doa.acoustic);
  };
  seed_support(array, seed);
  seed_support(best.partner_array, partner);
  for (int other = 0; other < array_count; ++other) {
    if (extra_index[other] >= 0)
      seed_support(other, recent[other][static_cast<std::size_t>(extra_index[other])]);
  }
  tracks.push_back(std::move(track));  // confirmed by life_cycle
  ++counters.tracks_started;

  seed.used = true;
  RecentDoa& partner_used = recent[best.partner_array][best.partner_index];
  partner_used.used = true;
  // The partner's tentative track had only one array since its first pair; the new track has
  // that array and another one now: it replaces it (else the older, sharper-looking one keeps
  // the array's DOAs by the assignment's cost and neither is ever confirmed).
  if (partner_used.weak_claimant_id >= 0) {
    const int replaced = partner_used.weak_claimant_id;
    const auto before = tracks.size();
    std::erase_if(tracks, [this, replaced](const Track& other) {
      return other.id == replaced && held_by_one_array(other);
    });
    counters.ghosts_rejected += static_cast<std::int64_t>(before - tracks.size());
    counters.tracks_deleted += static_cast<std::int64_t>(before - tracks.size());
  }
  for (int other = 0; other < array_count; ++other) {
    if (extra_index[other] >= 0) {
      recent[other][static_cast<std::size_t>(extra_index[other])].used = true;
    }
  }
  return true;
}

bool FusionEngine::Impl::try_start_one_array(int array, std::size_t recent_index, double time_s) {
  if (tracks.size() >= static_cast<std::size_t>(params.max_tracks)) return false;
  RecentDoa& seed = recent[array][recent_index];
  const DoaMeasurementModel& model = seed.model;
  const double gate = gate_for(model.dimension());
  // Not a new source if a track already explains the DOA: its predicted reading from this array,
  // with its position spread seen from its range, fits.
  for (const Track& track : tracks) {
    const Eigen::Vector3d to_track = position_of(track.filter->mean()) - model.centre_m;
    const double range_m = std::max(to_track.norm(), 1.0);
    const double spread_m2 = track.filter->covariance().topLeftCorner<3, 3>().trace() / 3.0;
    MeasurementCovariance r = seed.noise;
    r(0, 0) += spread_m2 / (range_m * range_m);
    if (model.dimension() == 2) r(1, 1) += spread_m2 / (range_m * range_m);
    const Measurement residual = model.residual(seed.z, model.predict_direction(to_track));
    if (residual.dot(r.ldlt().solve(residual)) <= gate) return false;
  }
  const double angle_std_rad =
      std::sqrt(model.dimension() == 1 ? seed.noise(0, 0) : 0.5 * seed.noise.trace());
  auto locus = bearing_locus(model, seed.z, angle_std_rad, seed.direction,
                             params.single_array.source_plane_z_m);
  if (!locus) return false;  // a cone with no source plane cannot start a track
  // No hypothesis under the ground: a ground echo's ray (the image a node reports as a second
  // source) then starts nothing.
  if (!params.single_array.source_plane_z_m) locus->min_altitude_m = params.ground_altitude_m;
  Track track;
  track.id = next_id;
  FilterSettings settings = one_array_settings;
  settings.random_seed = static_cast<std::uint64_t>(track.id);
  track.filter = make_track_filter(params.single_array_filter, settings);
  if (!track.filter->initialise_from_bearing(*locus)) return false;
  ++next_id;
  track.one_array = true;
  track.origin_array = array;
  track.origin_noise = seed.noise;
  track.time_s = time_s;
  track.last_update_s = time_s;
  track.heard_by_array_s.fill(kNeverS);
  track.hits_by_array[array] = 1u;
  track.heard_by_array_s[array] = time_s;
  track.updates_by_array[array] = 1;
  tracks.push_back(std::move(track));
  ++counters.tracks_started;
  seed.used = true;
  return true;
}

bool FusionEngine::Impl::refix_by_triangulation(Track& track, int origin_array,
                                                const MeasurementCovariance& origin_noise,
                                                const doa::DoaMeasurement& m,
                                                const DoaMeasurementModel& model, double time_s) {
  if (model.kind != MeasurementKind::azel) return false;  // a cone or a mirror pair: no one ray
  const Eigen::Vector3d origin = last_centre_m[static_cast<std::size_t>(origin_array)];
  const Eigen::Vector3d along = position_of(track.filter->mean()) - origin;
  if (!(along.norm() > 1.0)) return false;
  // The mixture's mean lies on the bearing (its hypotheses spread along it, not across).
  const std::array<Ray, 2> pair{Ray{origin, along.normalized(), origin_noise},
                                Ray{model.centre_m, m.direction, noise_of(m)}};
  const auto fix = triangulate(pair, params.triangulation);
  if (!fix || !fix->in_front || below_ground(*fix)) return false;
  // The rays must meet (two rays, three unknowns: one dof left), where the track says the source
  // may be: a DOA of another source that the wide mixture happened to gate is no hand-over.
  if (fix->chi_square > chi_square_quantile(params.gate_probability, 1)) return false;
  const Eigen::Vector3d offset = fix->position_m - position_of(track.filter->mean());
  const Eigen::Matrix3d spread =
      track.filter->covariance().topLeftCorner<3, 3>() + fix->covariance_m2;
  if (offset.dot(spread.ldlt().solve(offset)) > chi_square_quantile(params.gate_probability, 3))
    return false;
  StateVector mean;
  StateCovariance covariance;
  state_from_fix(*fix, model.centre_m, model.speed_of_sound_mps, mean, covariance);
  FilterSettings settings = filter_settings;
  settings.random_seed = static_cast<std::uint64_t>(track.id);
  auto filter = make_track_filter(params.filter, settings);
  filter->initialise(mean, covariance);
  track.filter = std::move(filter);
  track.time_s = time_s;
  track.one_array = false;
  return true;
}

void FusionEngine::Impl::hand_over(Track& track) {
  // Only a narrow Gaussian: a wide one (hypotheses merged while the range diffused) would be
  // linearised far from the truth by the next bearing.
  const double max_variance = params.max_position_std_m * params.max_position_std_m;
  if (track.filter->hypothesis_count() != 1 || recent_arrays(track) < 2 ||
      !(track.filter->covariance().diagonal().segment<3>(StateBlock::position).maxCoeff() <=
        max_variance))
    return;
  // A second array now resolves the range: the default filter (and motion model) takes the
  // collapsed Gaussian.
  FilterSettings settings = filter_settings;
  settings.random_seed = static_cast<std::uint64_t>(track.id);
  auto filter = make_track_filter(params.filter, settings);
  filter->initialise(track.filter->mean(), track.filter->covariance());
  track.filter = std::move(filter);
  track.one_array = false;
}

bool FusionEngine::Impl::beneath_another_track(const Track& track) const {
  const Eigen::Vector3d position = position_of(track.filter->mean());
  const Eigen::Matrix3d covariance = track.filter->covariance().topLeftCorner<3, 3>();
  for (const Track& other : tracks) {
    if (&other == &track || !other.confirmed) continue;
    const Eigen::Vector3d above = position_of(other.filter->mean());
    const double height_m = above.z() - params.ground_altitude_m;
    if (!(position.z() < above.z()) || !(position.z() - params.ground_altitude_m > -height_m))
      continue;
    const Eigen::Vector2d offset = (position - above).head<2>();
    const Eigen::Matrix2d spread = covariance.topLeftCorner<2, 2>() +
                                   other.filter->covariance().topLeftCorner<2, 2>() +
                                   Eigen::Matrix2d::Identity();  // 1 m: the echo's own blur
    if (offset.dot(spread.ldlt().solve(offset)) <= chi_square_quantile(0.999, 2)) return true;
  }
  return false;
}

int FusionEngine::Impl::last_array(const Track& track) const {
  int last = -1;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    if (track.heard_by_array_s[a] == kNeverS) continue;
    if (last < 0 || track.heard_by_array_s[a] > track.heard_by_array_s[last])
      last = static_cast<int>(a);
  }
  return last;
}

bool FusionEngine::Impl::lost(const Track& track, double now_s) const {
  // Only a range that two arrays did fix (each updated it confirm_hits times) is held open: a
  // track a pair started and no second array kept agreeing with (an outlier's) has none to hold.
  int fixing_arrays = 0;
  for (std::size_t a = 0; a < arrays.size(); ++a)
    if (track.updates_by_array[a] >= params.confirm_hits) ++fixing_arrays;
  if (fixing_arrays < 2) return true;
  // "Still hears it": that array updated it in confirm_hits of its last confirm_window frames (a
  // track that outliers of one array now and then keep alive does not qualify).
  const int last = last_array(track);
  const std::uint32_t window_mask =
      params.confirm_window >= 32 ? ~0u : ((1u << params.confirm_window) - 1u);
  if (last < 0 || now_s - track.heard_by_array_s[last] > kContributionMemoryS ||
      std::popcount(track.hits_by_array[static_cast<std::size_t>(last)] & window_mask) <
          params.confirm_hits)
    return true;
  const Eigen::Vector3d to_track =
      position_of(track.filter->mean()) - last_centre_m[static_cast<std::size_t>(last)];
  const double range_m = to_track.norm();
  if (!(range_m > 1.0)) return true;
  const Eigen::Vector3d along = to_track / range_m;
  const Eigen::Matrix3d spread = track.filter->covariance().topLeftCorner<3, 3>();
  const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - along * along.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(across * spread * across,
                                                              Eigen::EigenvaluesOnly);
  const double max_variance = params.max_position_std_m * params.max_position_std_m;
  return !(solver.eigenvalues().maxCoeff() <= max_variance) ||
         !(9.0 * along.dot(spread * along) < range_m * range_m);
}

bool FusionEngine::Impl::held_by_one_array(const Track& track) const {
  if (track.confirmed || track.one_array) return false;
  int holding = 0;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    if (track.updates_by_array[a] >= params.confirm_hits) {
      ++holding;
    } else if (track.updates_by_array[a] > 1) {
      return false;  // a second array did update it after its birth
    }
  }
  return holding == 1;
}

int FusionEngine::Impl::recent_arrays(const Track& track) const {
  int count = 0;
  for (std::size_t a = 0; a < arrays.size(); ++a)
    if (track.last_update_s - track.heard_by_array_s[a] <= kContributionMemoryS) ++count;
  return count;
}

bool FusionEngine::Impl::explained_by_other_tracks(const Track& track) const {
  const Eigen::Vector3d position = position_of(track.filter->mean());
  const double spread_m2 = track.filter->covariance().topLeftCorner<3, 3>().trace() / 3.0;
  const int support = recent_arrays(track);
  int supporting = 0;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    if (track.last_update_s - track.heard_by_array_s[a] > kContributionMemoryS) continue;
    ++supporting;
    const Eigen::Vector3d to_track = position - last_centre_m[a];
    const double range_m = std::max(to_track.norm(), 1.0);
    bool explained = false;
    for (const Track& other : tracks) {
      // Only a track with better standing explains: confirmed, or heard by more arrays (a ghost
      // and the drone whose ray it shares explain each other from that array; the drone also
      // has the arrays the ghost lacks).
      if (&other == &track || !(other.confirmed || recent_arrays(other) > support)) continue;
      const Eigen::Vector3d to_other = position_of(other.filter->mean()) - last_centre_m[a];
      const double other_range_m = std::max(to_other.norm(), 1.0);
      const double other_spread_m2 = other.filter->covariance().topLeftCorner<3, 3>().trace() / 3.0;
      const double angle_rad =
          std::acos(std::clamp(to_track.dot(to_other) / (range_m * other_range_m), -1.0, 1.0));
      const double variance_rad2 = floor_variance_rad2 + spread_m2 / (range_m * range_m) +
                                   other_spread_m2 / (other_range_m * other_range_m);
      if (angle_rad * angle_rad <= gate_chi2 * variance_rad2) {
        explained = true;
        break;
      }
    }
    if (!explained) return false;
  }
  return supporting > 0;
}

bool FusionEngine::Impl::spectra_disagree(const Track& track) const {
  // Only an array that gave the track enough analysed DOAs to say what it hears: a comb in most
  // of them, or in few. A comb found now and then (a weak source near the detector's floor)
  // says neither.
  constexpr double kCombShare = 0.75;
  constexpr double kNoCombShare = 0.25;
  // Two arrays hear one source's comb spacing shifted by its Doppler towards each, at most
  // 2 v / c apart, plus the detector's own spread (a few %). The detector takes the smallest
  // spacing that correlates nearly as well as the best, so it does not report a multiple. Every
  // array's model carries the site's one speed of sound.
  const double tolerance =
      2.0 * params.init_max_speed_mps / models.front().speed_of_sound_mps + 0.05;
  bool comb_heard = false;
  bool no_comb_heard = false;
  double lowest_hz = std::numeric_limits<double>::infinity();
  double highest_hz = 0.0;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    const AcousticTally& tally = track.acoustic_by_array[a];
    if (tally.analysed < params.confirm_hits) continue;
    const double share = static_cast<double>(tally.with_comb) / tally.analysed;
    if (share <= kNoCombShare) no_comb_heard = true;
    if (share < kCombShare) continue;
    comb_heard = true;
    const double fundamental_hz = tally.fundamental_sum_hz / tally.with_comb;
    lowest_hz = std::min(lowest_hz, fundamental_hz);
    highest_hz = std::max(highest_hz, fundamental_hz);
  }
  if (comb_heard && no_comb_heard) return true;
  return highest_hz > lowest_hz * (1.0 + tolerance);
}

void FusionEngine::Impl::confirm_tracks(double now_s) {
  const std::uint32_t window_mask =
      params.confirm_window >= 32 ? ~0u : ((1u << params.confirm_window) - 1u);
  const int min_arrays = std::min<int>(params.confirm_min_arrays, static_cast<int>(arrays.size()));
  for (Track& track : tracks) {
    if (track.confirmed) continue;
    int arrays_heard = 0;
    int arrays_repeating = 0;  // arrays that updated it at confirm_hits distinct times
    int hits = 0;
    int updates = 0;
    for (std::size_t a = 0; a < arrays.size(); ++a) {
      updates += track.updates_by_array[a];
      if (track.heard_by_array_s[a] != kNeverS) ++arrays_heard;
      if (track.updates_by_array[a] >= params.confirm_hits) ++arrays_repeating;
      hits += std::popcount(track.hits_by_array[a] & window_mask);
    }
    // Ghost rejection (confirm_min_arrays): a crossing of two drones' rays is consistent with the
    // two arrays that made it at one moment, rarely with a third. A drone only two arrays can hear
    // (the others masked by a louder drone) gives the same evidence by continuity in time: two
    // rays in 3-D are skew unless they meet at the drone, so a ghost does not keep taking DOAs of
    // both arrays while the drones move. Both arrays must have updated it confirm_hits times.
    // The initiating pair agrees by construction, so two distinct arrays are no evidence: on a
    // two-array site (min_arrays clamped to 2) continuity decides, not the pair's first fix.
    // A one-array track (issue 15) has only continuity: its array updated it confirm_hits times.
    const bool supported = (arrays_heard >= min_arrays && (arrays_heard > 2 || min_arrays <= 1)) ||
                           arrays_repeating >= 2 || (track.one_array && arrays_repeating >= 1);
    // Nor is a track under the ground by more than its own uncertainty: where two drones' rays
    // (or a drone's and its ground image's) cross low, a ghost starts near the ground and sinks.
    const double altitude_m = track.filter->mean()(StateBlock::position + 2);
    const double altitude_std_m = std::sqrt(std::max(
        track.filter->covariance()(StateBlock::position + 2, StateBlock::position + 2), 0.0));
    const bool above_ground = altitude_m + altitude_std_m >= params.ground_altitude_m;
    // Outlier-born (issue 17): most of its DOAs came in frames whose arrays had none to spare
    // beyond the confirmed tracks they hear. An impulsive outlier takes the place of a confirmed
    // track's DOA; a second source adds a DOA to the frame.
    const bool displacing = 2 * track.crowded_updates > updates;
    if (supported && above_ground && hits >= params.confirm_hits && !displacing &&
        !explained_by_other_tracks(track) && !beneath_another_track(track) &&
        !spectra_disagree(track)) {
      track.confirmed = true;
      track.confirmed_at_s = now_s;
      ++counters.tracks_confirmed;
    }
  }
}

void FusionEngine::Impl::life_cycle(double now_s) {
  for (Track& track : tracks) {
    const StateVector& mean = track.filter->mean();
    const double altitude_std_m = std::sqrt(std::max(
        track.filter->covariance()(StateBlock::position + 2, StateBlock::position + 2), 0.0));
    classifier->add_kinematics(track.evidence, position_of(mean), velocity_of(mean), altitude_std_m,
                               track.time_s);
    classifier->classify(track.evidence);
  }
  delete_expired(now_s);
}

void FusionEngine::Impl::delete_expired(double now_s) {
  const double max_variance = params.max_position_std_m * params.max_position_std_m;
  const auto dead = [&](const Track& track) {
    const bool unconfirmed_expired =
        !track.confirmed && now_s - track.last_update_s > params.tentative_timeout_s;
    if (unconfirmed_expired) ++counters.ghosts_rejected;
    const Eigen::Vector3d variance =
        track.filter->covariance().diagonal().segment<3>(StateBlock::position);
    if (!variance.allFinite()) return true;
    // A one-array track's spread along its bearing is what it knows, not a lost track; it ends
    // by timeout.
    if (!track.one_array && !(variance.maxCoeff() <= max_variance) && lost(track, now_s))
      return true;
    const double unheard = now_s - track.last_update_s;
    return unheard > (track.confirmed ? params.coast_timeout_s : params.tentative_timeout_s);
  };
  const auto before = tracks.size();
  tracks.erase(std::remove_if(tracks.begin(), tracks.end(), dead), tracks.end());
  counters.tracks_deleted += static_cast<std::int64_t>(before - tracks.size());
}

void FusionEngine::tracks_at(double time_s, std::vector<TrackReport>& out) const {
  const Impl& s = *impl_;
  out.clear();
  for (const Track& track : s.tracks) {
    TrackReport report;
    report.id = track.id;
    report.time_s = time_s;
    StateVector mean = track.filter->mean();
    StateCovariance covariance = track.filter->covariance();
    s.filter_settings.motion.predict(mean, covariance, std::max(time_s - track.time_s, 0.0));
    report.position_m = position_of(mean);
    report.velocity_mps = velocity_of(mean);
    report.acceleration_mps2 = acceleration_of(mean);
    report.covariance = covariance;
    report.last_update_s = track.last_update_s;
    report.track_class = track.evidence.track_class;
    report.class_confidence = track.evidence.confidence;
    report.confirmed_s = track.confirmed ? time_s - track.confirmed_at_s : -1.0;
    report.one_array = track.one_array;
    report.hypotheses = track.filter->hypothesis_count();
    if (!track.confirmed) {
      report.status = TrackStatus::tentative;
    } else if (time_s - track.last_update_s > s.params.coast_after_s) {
      report.status = TrackStatus::coasting;
    } else {
      report.status = TrackStatus::confirmed;
    }
    for (std::size_t a = 0; a < s.arrays.size(); ++a) {
      if (time_s - track.heard_by_array_s[a] <= kContributionMemoryS) {
        report.contributing_arrays |= std::uint64_t{1} << a;
      }
    }
    out.push_back(report);
  }
}

const FusionCounters& FusionEngine::counters() const { return impl_->counters; }
const std::vector<doa::ArrayGeometry>& FusionEngine::arrays() const { return impl_->arrays; }

}  // namespace dronetrack::fusion
