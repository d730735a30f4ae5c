// NodePipeline: the composition of the node's stages, one frame at a time:
//   Framer -> MultichannelFft -> GccPhat -> DetectionGate -> TdoaEstimator -> LsDoaSolver
//                                        \-> SrpPhat (further sources) -> LsDoaSolver
// With robust_regression the frame's sources are found per frame (per-frame peaks, then SRP),
// and SourceTracks smooths each source's TDOAs over time on one time base before the final solve.
// Beside the frames, ChannelHealth counts and judges every channel's samples as they come.
// Everything is sized in the constructor; process() only appends to the caller's vector.
// Several bands with per_band_detection (issue 15, seed 003: one source per band): PerBand runs
// one such composition per band, each on its band alone, and merges their DOAs by time.
#include "doa/node_pipeline.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "doa/acoustic_features.hpp"
#include "doa/array_health.hpp"
#include "doa/bin_snr_weight.hpp"
#include "doa/channel_health.hpp"
#include "doa/cone_peaks.hpp"
#include "doa/detection_gate.hpp"
#include "doa/gcc_phat.hpp"
#include "doa/ground_echo.hpp"
#include "doa/ls_doa_solver.hpp"
#include "doa/source_bin_mask.hpp"
#include "doa/source_tracks.hpp"
#include "doa/spectral_frame.hpp"
#include "doa/srp_phat.hpp"
#include "doa/static_source_null.hpp"
#include "doa/tdoa_tracker.hpp"

namespace dronetrack::doa {

namespace {

constexpr int kMaxSources = 8;
// Per-band detection: source_index = band + bands x rank < 64, the fusion's per-array source mask.
constexpr int kMaxDetectionBands = 8;

// A narrow band far from DC correlates as fringes one carrier period (1/f_c) apart under an
// envelope ~1/B wide, the neighbours nearly as high as the peak (sinc(B / f_c): 0.89 for 30-39
// kHz). The lag grid (2 f_high x correlation_oversample samples a second) finds the peak's
// fringe, so it must sample the fringes densely enough that the true one is not undercut by
// where its samples fall: at 2.3 samples a fringe (30-39 kHz, oversample 1) a neighbour won in
// most frames at some angles (4.2 deg on a 0.6 m pair, BandSources.NarrowBandFarFromDc...); at
// >= 8 a fringe, never. The oversample giving >= 8 grid samples per period of the band centre.
int fringe_oversample(const FrequencyBand& band) {
  const double centre_hz = 0.5 * (band.low_hz + band.high_hz);
  return std::clamp(static_cast<int>(std::ceil(4.0 * centre_hz / band.high_hz)), 1, 16);
}

// A node per band: several bands listed, and the config asks for each on its own.
bool splits_bands(const DoaParams& params) {
  return params.per_band_detection && params.bands_hz.size() > 1;
}
// With SNR weighting the static null observes a plain-PHAT look every this many frames (0.1 s
// at the default hop; it learns over static_null_learn_s = 3 s). Every 4th frame left the
// generator of the ground-interferer scene un-nulled at A2 for 10 s instead of 3 s.
constexpr std::int64_t kStaticNullLookFrames = 2;

std::string setup_problem(const ArrayGeometry& geometry, const DoaParams& params,
                          double sample_rate_hz, double speed_of_sound_mps) {
  std::string problem;
  auto fail = [&](const std::string& what) {
    if (problem.empty()) problem = what;
  };
  if (!(sample_rate_hz >= 1000.0 && sample_rate_hz <= 1e6))
    fail("sample_rate_hz must be in [1000, 1e6], got " + std::to_string(sample_rate_hz));
  if (!(speed_of_sound_mps > 0.0)) fail("speed_of_sound_mps must be > 0");
  if (geometry.mic_count() < 2) fail("needs at least 2 mics");
  if (geometry.mic_count() > 8) fail("at most 8 mics are supported");
  if (!(params.frame_s > 0.0) || !(params.hop_s > 0.0) || params.hop_s > params.frame_s)
    fail("need 0 < hop_s <= frame_s");
  if (params.bands_hz.empty()) fail("bands_hz needs at least one band");
  if (params.max_sources < 1 || params.max_sources > kMaxSources)
    fail("max_sources must be in [1, 8]");
  if (params.correlation_oversample < 1 || params.correlation_oversample > 16)
    fail("correlation_oversample must be in [1, 16]");
  if (params.regression_window_frames < 5 || params.regression_window_frames > 64)
    fail("regression_window_frames must be in [5, 64]");
  if (params.regression_delay_frames < 0 ||
      params.regression_delay_frames >= params.regression_window_frames)
    fail("regression_delay_frames must be in [0, regression_window_frames)");
  if (!problem.empty()) return problem;
  // A pair's delay must fit well inside a frame, or its correlation peak is not in the frame.
  const double frame_s = std::lround(params.frame_s * sample_rate_hz) / sample_rate_hz;
  for (std::size_t i = 0; i < geometry.mic_count(); ++i) {
    for (std::size_t j = i + 1; j < geometry.mic_count(); ++j) {
      const double delay_s = (geometry.mics_m[i] - geometry.mics_m[j]).norm() / speed_of_sound_mps;
      if (delay_s > 0.5 * frame_s) {
        return "mics " + std::to_string(i) + " and " + std::to_string(j) + " are " +
               std::to_string(delay_s * speed_of_sound_mps) + " m apart: their delay (" +
               std::to_string(delay_s) + " s) exceeds half a frame (doa.frame_s " +
               std::to_string(params.frame_s) + " s)";
      }
    }
  }
  const int frame_length = static_cast<int>(std::lround(params.frame_s * sample_rate_hz));
  try {
    (void)band_runs(params.bands_hz, sample_rate_hz, fftw_friendly_size(frame_length));
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  if (!splits_bands(params)) return problem;
  if (params.bands_hz.size() > static_cast<std::size_t>(kMaxDetectionBands))
    return "per_band_detection takes at most " + std::to_string(kMaxDetectionBands) +
           " bands, got " + std::to_string(params.bands_hz.size()) +
           " (per_band_detection false: their union as one band)";
  for (std::size_t b = 0; b < params.bands_hz.size(); ++b) {
    try {
      (void)band_runs({params.bands_hz[b]}, sample_rate_hz, fftw_friendly_size(frame_length));
    } catch (const std::invalid_argument& error) {
      return "bands_hz[" + std::to_string(b) + "] (per_band_detection): " + error.what();
    }
  }
  return problem;
}

void validate(const ArrayGeometry& geometry, const DoaParams& params, double sample_rate_hz,
              double speed_of_sound_mps) {
  const std::string problem = setup_problem(geometry, params, sample_rate_hz, speed_of_sound_mps);
  if (!problem.empty()) throw std::invalid_argument("array " + geometry.id + ": " + problem);
}

std::vector<MicPairSpec> pair_specs(const LsDoaSolver& solver) {
  std::vector<MicPairSpec> pairs;
  for (int p = 0; p < solver.pair_count(); ++p)
    pairs.push_back({solver.pair_mic_i(p), solver.pair_mic_j(p), solver.max_lag_s(p)});
  return pairs;
}

LsDoaSettings solver_settings(const DoaParams& params, double speed_of_sound_mps) {
  LsDoaSettings settings;
  settings.speed_of_sound_mps = speed_of_sound_mps;
  settings.max_norm_error = params.max_norm_error;
  settings.max_chi2_per_dof = params.max_chi2_per_dof;
  return settings;
}

// Standard deviation of the SRP power (mean over pairs of the PHAT correlation at one lag) of
// incoherent noise: each band bin adds a unit phasor of random phase, Re of which has variance
// 1/2; the Hann window makes ~1.5 neighbouring bins share one phase, zero padding more.
double srp_noise_sigma(const std::vector<BandRun>& band, int frame_length, int fft_size,
                       int pair_count) {
  double bins = 0.0;
  for (const BandRun& run : band) bins += run.last_bin - run.first_bin + 1;
  const double independent_bins =
      std::max(1.0, bins * frame_length / (1.5 * static_cast<double>(fft_size)));
  return std::sqrt(1.0 / (2.0 * independent_bins * pair_count));
}

// A channel is said to clip when more of a stretch clips than a frame may hold and still give
// a DOA.
ChannelHealthSettings health_settings(const DoaParams& params) {
  ChannelHealthSettings settings;
  settings.clipped_share = params.max_clipped_fraction;
  return settings;
}

// A pair hears the array-health checks' source at the peak the node needs to publish.
ArrayHealthSettings array_health_settings(const DoaParams& params) {
  ArrayHealthSettings settings;
  settings.coherent_peak = std::clamp(params.min_gcc_peak, 0.05, 0.95);
  return settings;
}

}  // namespace

std::string NodePipeline::setup_problem(const ArrayGeometry& geometry, const DoaParams& params,
                                        double sample_rate_hz, double speed_of_sound_mps) {
  return dronetrack::doa::setup_problem(geometry, params, sample_rate_hz, speed_of_sound_mps);
}

struct NodePipeline::Impl {
  Impl(ArrayGeometry geometry_in, int array_index_in, const DoaParams& params_in,
       double sample_rate_hz_in, double speed_of_sound_mps)
      : geometry(std::move(geometry_in)),
        array_index(array_index_in),
        params(params_in),
        sample_rate_hz(sample_rate_hz_in),
        frame_length(static_cast<int>(std::lround(params.frame_s * sample_rate_hz))),
        hop(std::max(1, static_cast<int>(std::lround(params.hop_s * sample_rate_hz)))),
        solver(geometry, solver_settings(params, speed_of_sound_mps)),
        framer(static_cast<int>(geometry.mic_count()), frame_length, hop),
        fft(static_cast<int>(geometry.mic_count()), frame_length, fftw_friendly_size(frame_length)),
        gcc(fft.fft_size(), frame_length, sample_rate_hz, params.bands_hz, pair_specs(solver),
            params.lag_interpolation, params.correlation_oversample),
        gate(DetectionSettings{params.detection_snr_db, params.min_gcc_peak,
                               params.noise_floor_rise_db_per_s, 0.5, -130.0},
             params.hop_s),
        band(band_runs(params.bands_hz, sample_rate_hz, fft.fft_size())),
        health(static_cast<int>(geometry.mic_count()), sample_rate_hz, health_settings(params)),
        array_health(geometry, speed_of_sound_mps, static_cast<double>(hop) / sample_rate_hz,
                     array_health_settings(params)) {
    if (!geometry.channel_delay_s.empty() || !geometry.channel_gain_db.empty()) {
      std::vector<double> delay_samples;
      for (double delay_s : geometry.channel_delay_s)
        delay_samples.push_back(delay_s * sample_rate_hz);
      fft.set_channel_corrections(delay_samples, geometry.channel_gain_db);
    }
    TdoaTrackerSettings tracker_settings;
    tracker_settings.hop_s = static_cast<double>(hop) / sample_rate_hz;
    tracker_settings.max_angular_rate_dps = params.max_angular_rate_dps;
    tracker_settings.regression_window_frames = params.regression_window_frames;
    tracker_settings.regression_delay_frames = params.regression_delay_frames;
    tracker_settings.frame_overlap_variance_factor = fft.overlap_variance_factor(hop);
    // The regression smooths each source found per frame (SourceTracks); the grid trackers
    // follow the strongest source on the correlations themselves.
    if (params.tdoa_tracker == TdoaTracker::robust_regression) {
      tracker = make_tdoa_estimator(TdoaTracker::per_frame, gcc, tracker_settings);
      source_tracks = std::make_unique<SourceTracks>(
          solver.pair_count(), std::min(kMaxSources, 2 * params.max_sources), tracker_settings,
          0.5 * params.srp_min_separation_deg);
    } else {
      tracker = make_tdoa_estimator(params.tdoa_tracker, gcc, tracker_settings);
    }
    tdoas.resize(static_cast<std::size_t>(solver.pair_count()));
    srp_noise_floor = params.srp_min_power_sigmas *
                      srp_noise_sigma(band, frame_length, fft.fft_size(), solver.pair_count());
    if (params.static_null && params.static_null_max_sources > 0)
      static_null = std::make_unique<StaticSourceNull>(
          geometry, gcc, static_null_settings(params, tracker_settings.hop_s, speed_of_sound_mps));
    if (params.snr_weighting)
      snr_weight =
          std::make_unique<BinSnrWeight>(gcc.band(), tracker_settings.hop_s,
                                         params.snr_noise_rise_db_per_s, params.snr_weight_floor);
    if (params.acoustic.enabled)
      acoustic = std::make_unique<AcousticFeatureExtractor>(
          geometry, fft.fft_size(), sample_rate_hz, speed_of_sound_mps, tracker_settings.hop_s,
          params.acoustic);
    // A two-mic array publishes its GCC's strongest peaks as cone angles (seed 004).
    if (solver.rank() == 1) {
      gcc.set_peak_count(kMaxConePeaks);
      cone_peaks = std::make_unique<ConePeakHistory>(solver, tracker_settings.hop_s);
    }
    if (params.max_sources > 1 && solver.rank() >= 2) {
      srp = std::make_unique<SrpPhat>(solver, gcc, params.srp_grid_deg);
    }
    // A planar or linear array cannot tell the echo (mirrored elevation) from the source, and a
    // horizontal one hears the same comb at every mic: no differential phase to remove.
    if (params.ground_echo && solver.rank() >= 3) {
      GroundEchoSettings echo_settings;
      echo_settings.ground_height_m = params.ground_height_m;
      ground_echoes.assign(static_cast<std::size_t>(params.max_sources),
                           GroundEcho(geometry, gcc, speed_of_sound_mps, echo_settings));
    }
  }

  struct Candidate {
    DoaSolution solution;
    std::array<PairTdoa, kMaxPairs> tdoas{};
    double coherence = 0.0;
    double time_offset_s = 0.0;  // the tracker's output delay (primary only)
    int slot = -1;               // its acoustic history (source track slot, or its index)
  };

  void analyse(const FrameView& frame, std::vector<DoaMeasurement>& out);
  void find_candidates();
  void find_further_sources();
  void mask_source(std::span<const PairTdoa> source_tdoas, bool null_observes = false);
  void null_observe();
  void null_own_look();
  bool below_horizon(const DoaSolution& solution);
  bool already_found(const Eigen::Vector3d& direction_site) const;
  // near_known_lags: the peaks moved by a small correction only (the ground echo's, well under
  // a grid step): Newton from the known lags, no lag grids.
  void remeasure(int source, bool near_known_lags = false);
  void remove_ground_echoes();
  // weighted: the phasors made with the SNR weights on (for a weighted correlation next).
  void only_bins_of(int source, bool weighted = false);
  void remove_ground_echo(int source, GroundEcho& echo);
  void smooth_candidates(double time_s);
  // This frame's sources' spectra into their slots' acoustic histories (every few frames).
  // acoustic_directions/slots/generations hold `count` sources.
  void measure_acoustics(int count);
  bool was_detecting(double time_s) const;
  // Only the per-source regression reports an earlier frame; the per-pair trackers are current.
  double output_delay_s() const { return source_tracks ? source_tracks->output_delay_s() : 0.0; }
  double mean_coherence(std::span<const PairTdoa> used) const;
  // The frame's correlations are as sharp as publishing needs, whatever their main lobes' sign:
  // a flipped mic's pairs peak negative, which neither `sharp` nor the gate's SNR (its floor
  // counts what is not coherent at the positive peaks) would call a source.
  bool sharp_either_sign() const {
    double sum = 0.0;
    for (int p = 0; p < gcc.pair_count(); ++p) {
      const PairPeak& pair = health_pairs[static_cast<std::size_t>(p)];
      sum += std::max(pair.highest, -pair.lowest);
    }
    return sum >= params.min_gcc_peak * gcc.pair_count();
  }
  // Mean over channels; each channel's into channel_power.
  double inband_power();
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
  double min_elevation_sine = std::sin(params.min_elevation_deg * std::numbers::pi / 180.0);
  double separation_cosine = std::cos(params.srp_min_separation_deg * std::numbers::pi / 180.0);
  std::unique_ptr<StaticSourceNull> static_null;       // static ground sources' bins dropped
  std::unique_ptr<BinSnrWeight> snr_weight;            // noise-only bins faded
  std::unique_ptr<AcousticFeatureExtractor> acoustic;  // each source's spectral features
  bool acoustic_due = false;                           // this frame is measured
  std::array<Eigen::Vector3d, kMaxSources> acoustic_directions{};
  std::array<int, kMaxSources> acoustic_slots{};
  std::array<std::uint32_t, kMaxSources> acoustic_generations{};
  // Each source's ground reflection (its range and strength are its own), following the sources
  // by direction; empty for arrays that cannot tell the echo from the source.
  std::vector<GroundEcho> ground_echoes;
  std::unique_ptr<SourceTracks> source_tracks;
  std::unique_ptr<ConePeakHistory> cone_peaks;  // rank 1 only
  std::array<SourceObservation, kMaxSources> observations{};
  std::array<SourceEstimate, kMaxSources> estimates{};
  struct FrameDetection {
    double time_s = -1e300;
    bool detecting = false;
  };
  std::array<FrameDetection, 64> recent_detections{};  // ring: was the gate open at that frame
  std::size_t next_detection = 0;
  std::vector<PairTdoa> tdoas;
  std::array<Candidate, kMaxSources> candidates{};
  int candidate_count = 0;
  // This frame's static-null observation (SNR weighting on): wanted, made, and on what time and
  // frame condition.
  bool null_wanted = false;
  bool null_observed = false;
  double null_time_s = 0.0;
  bool null_frame_clean = false;
  NodeDiagnostics diagnostics;
  PoseStamp fixed_pose = fixed_stamp(geometry);
  PoseTrack pose_track;            // empty: a fixed array
  double sound_speed_mps = 343.0;  // for the Doppler correction
};

// The static null learns from plain PHAT peaks: a steady ground source is as steady in power as
// the noise floor, so the SNR weights fade it and it would rarely be the strongest. It learns
// over seconds, so one look every kStaticNullLookFrames frames is enough, and a look the frame
// makes anyway serves: the plain re-correlation without the first source's bins (a drone's
// bins gone, the ground source stands out more than in the full band), or the weighted look
// itself when its strongest source is below the horizon (it is the ground source). Only a
// frame without either gets a plain look of its own (null_own_look).
void NodePipeline::Impl::null_observe() {
  double peak_sum = 0.0;
  for (int p = 0; p < gcc.pair_count(); ++p) peak_sum += gcc.pair(p).peak.value;
  static_null->observe(null_time_s, gcc,
                       null_frame_clean && peak_sum >= params.min_gcc_peak * gcc.pair_count());
  diagnostics.static_sources_nulled = static_null->nulled_count();
  null_observed = true;
}

// The full band in plain PHAT with only the static null's mask, as whiten() and mask() left
// it (save_whitened() in analyse()).
void NodePipeline::Impl::null_own_look() {
  gcc.restore_whitened();
  gcc.correlate(true, false);
  null_observe();
}

double NodePipeline::Impl::inband_power() {
  // Parseval: one-sided bins count twice; per windowed sample.
  const double scale = 2.0 / (static_cast<double>(fft.fft_size()) * fft.window_energy());
  double total = 0.0;
  for (int c = 0; c < fft.channels(); ++c) {
    const std::complex<double>* spectrum = fft.spectrum(c);
    double power = 0.0;
    for (const BandRun& run : band)
      for (int k = run.first_bin; k <= run.last_bin; ++k) power += std::norm(spectrum[k]);
    channel_power[static_cast<std::size_t>(c)] = scale * power;
    total += power;
  }
  return scale * total / fft.channels();
}

bool NodePipeline::Impl::publish(const Candidate& candidate, double time_s, int source_index,
                                 std::vector<DoaMeasurement>& out) {
  const DoaSolution solution = doppler_corrected(candidate, time_s);
  const std::span<const PairTdoa> used(candidate.tdoas.data(), tdoas.size());
  DoaMeasurement measurement;
  measurement.array_id = geometry.id;
  measurement.array_index = array_index;
  measurement.time_s = time_s - geometry.clock_offset_s;  // on the site's clock
  measurement.direction = solution.direction_site;
  measurement.azel_covariance_rad2 = solution.azel_covariance_rad2;
  measurement.quality = solution.quality;
  measurement.snr_db = gate.snr_db();
  measurement.source_index = source_index;
  measurement.ambiguity = solution.ambiguity;
  measurement.ambiguity_axis = solution.ambiguity_axis_site;
  measurement.cone_angle_rad = solution.cone_angle_rad;
  measurement.cone_angle_variance_rad2 = solution.cone_angle_variance_rad2;
  if (cone_peaks) cone_peaks->fill(time_s, measurement);
  measurement.pair_count = solver.pair_count();
  for (int p = 0; p < solver.pair_count(); ++p)
    measurement.tdoa_s[static_cast<std::size_t>(p)] = used[static_cast<std::size_t>(p)].tdoa_s;
  if (acoustic && candidate.slot >= 0) measurement.acoustic = acoustic->features(candidate.slot);
  if (!stamp_pose(measurement)) return false;
  out.push_back(std::move(measurement));
  ++diagnostics.doas_published;
  return true;
}

// Everything before publishing works in the frame of the geometry's fixed attitude (the solver's
// rotation, the ground echo, the horizon); a moving array's DOA is turned to the attitude at its
// time here, and only here.
bool NodePipeline::Impl::stamp_pose(DoaMeasurement& measurement) {
  if (pose_track.empty()) {
    measurement.pose = fixed_pose;
    return true;
  }
  const std::optional<PoseStamp> stamp = pose_track.stamp(measurement.time_s, geometry);
  if (!stamp) {
    ++diagnostics.unposed_doas;
    return false;
  }
  restamp(measurement, *stamp, solver.array_to_site());
  return true;
}

// A platform moving at v towards the source shortens every TDOA alike: measured = true /
// (1 + u.v / c), 0.5 % at 2 m/s. The plane-wave fit is blind to a common scale, but the
// near-field refinement reads it as wavefront curvature and bends the direction (0.7 deg for a
// platform driving at 2 m/s and turning at 15 deg/s), and the chi^2 gate of a plain plane-wave
// fit would refuse it. So: solved again on the TDOAs scaled back by the pose track's velocity,
// with u from the first solve (its error is far below what moves the scale). Only for a full
// direction: a cone or mirror pair does not know u.
DoaSolution NodePipeline::Impl::doppler_corrected(const Candidate& candidate, double time_s) const {
  if (pose_track.empty() || !candidate.solution.accepted ||
      candidate.solution.ambiguity != DoaAmbiguity::none)
    return candidate.solution;
  const std::optional<Eigen::Vector3d> velocity_site = pose_track.velocity_mps(time_s);
  const std::optional<PoseStamp> stamp = pose_track.stamp(time_s, geometry);
  if (!velocity_site || !stamp) return candidate.solution;
  // The solver's frame is the config pose's: the velocity as that frame sees it.
  const Eigen::Vector3d velocity =
      solver.array_to_site() * (stamp->array_to_site.conjugate() * *velocity_site);
  const double scale = 1.0 + candidate.solution.direction_site.dot(velocity) / sound_speed_mps;
  std::array<PairTdoa, kMaxPairs> scaled = candidate.tdoas;
  for (PairTdoa& pair : scaled) pair.tdoa_s *= scale;
  const DoaSolution solution = solver.solve(std::span<const PairTdoa>(scaled.data(), tdoas.size()));
  return solution.accepted ? solution : candidate.solution;
}

double NodePipeline::Impl::mean_coherence(std::span<const PairTdoa> used) const {
  double sum = 0.0;
  int count = 0;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairTdoa& tdoa = used[static_cast<std::size_t>(p)];
    if (!(tdoa.variance_s2 > 0.0)) continue;
    sum += tdoa.coherence;
    ++count;
  }
  return count > 0 ? sum / count : 0.0;
}

// Below the horizon mask a source is on the ground (a generator, a road) or is the ground's
// reflection of a drone (its mirror image, as loud as -6 dB): not a target, and left out of
// the next look's bins. Only a 3-D array knows up from down.
bool NodePipeline::Impl::below_horizon(const DoaSolution& solution) {
  if (solver.rank() < 3 || solution.direction_site.z() >= min_elevation_sine) return false;
  ++diagnostics.below_horizon_rejected;
  return true;
}

// Within srp_min_separation_deg of a source already in this frame's candidates: the same one.
bool NodePipeline::Impl::already_found(const Eigen::Vector3d& direction_site) const {
  for (int s = 0; s < candidate_count; ++s)
    if (direction_site.dot(candidates[static_cast<std::size_t>(s)].solution.direction_site) >=
        separation_cosine)
      return true;
  return false;
}

void NodePipeline::Impl::find_candidates() {
  candidate_count = 0;
  Candidate& primary = candidates[0];
  primary.solution = solver.solve(tdoas);
  const bool primary_below_horizon = primary.solution.accepted && below_horizon(primary.solution);
  if (primary_below_horizon && null_wanted) null_observe();
  if (primary_below_horizon) mask_source(tdoas);
  if (primary.solution.accepted && !primary_below_horizon) {
    std::copy(tdoas.begin(), tdoas.end(), primary.tdoas.begin());
    primary.coherence = mean_coherence(tdoas);
    primary.time_offset_s = 0.0;
    ++candidate_count;
  }
  gcc.save_whitened();
  if (srp) find_further_sources();
  // A frame whose looks gave the static null nothing to observe: its own look, before the echo
  // removal rotates the mics' units.
  if (null_wanted && !null_observed) null_own_look();
  if (!ground_echoes.empty()) remove_ground_echoes();
}

// Each source found takes its bins out of the correlations before the next look: what is left is
// normalised over the bins the louder sources do not own, so a weaker drone's peak is neither
// buried under the louder one's lobes nor pulled by them.
void NodePipeline::Impl::find_further_sources() {
  if (candidate_count > 0) mask_source(tdoas, null_wanted && !null_observed);
  srp->begin_frame(gcc);
  // A few more looks than sources: a look whose TDOAs do not fit is cancelled and skipped.
  for (int look = 0; look < params.max_sources + 2 && candidate_count < params.max_sources;
       ++look) {
    // Incoherent noise over fewer bins correlates more by chance. Nothing under the floor is
    // used: the search may skip what cannot reach it.
    const double floor = srp_noise_floor * std::sqrt(static_cast<double>(gcc.band_bin_count()) /
                                                     std::max(1, gcc.kept_bin_count()));
    SrpPeak peak;
    if (!srp->strongest(peak, floor)) break;
    Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
    const std::span<PairTdoa> candidate_tdoas(candidate.tdoas.data(), tdoas.size());
    srp->tdoas_near(gcc, peak.direction_array, candidate_tdoas);
    candidate.solution = solver.solve(candidate_tdoas);
    const bool duplicate =
        !candidate.solution.accepted || already_found(candidate.solution.direction_site);
    if (!duplicate && below_horizon(candidate.solution)) {
      mask_source(candidate_tdoas);
      srp->begin_frame(gcc);
      continue;
    }
    if (duplicate) {
      srp->subtract_direction(gcc, peak.direction_array);
      continue;
    }
    candidate.coherence = mean_coherence(candidate_tdoas);
    candidate.time_offset_s = 0.0;
    ++candidate_count;
    if (candidate_count < params.max_sources) {
      mask_source(candidate_tdoas);
      srp->begin_frame(gcc);
    }
  }
  if (candidate_count >= 2) remeasure(0);
}

// The frame's whitened phasors again, minus every other candidate's bins.
void NodePipeline::Impl::only_bins_of(int source, bool weighted) {
  gcc.restore_whitened(weighted);
  for (int s = 0; s < candidate_count; ++s)
    if (s != source)
      bin_mask.drop(gcc, std::span<const PairTdoa>(
                             candidates[static_cast<std::size_t>(s)].tdoas.data(), tdoas.size()));
}

// Every source's ground reflection, found on its own bins (the others' dropped), divided out of
// the mics' phases; its TDOAs are then measured again and the units put back for the next.
void NodePipeline::Impl::remove_ground_echoes() {
  // Each state goes to the source it followed: pairs taken best-aligned first, so a stray look
  // cannot take the state of a drone that is still there (a new source gets a free state, which
  // then searches afresh: a jump).
  std::array<bool, kMaxSources> state_taken{};
  std::array<int, kMaxSources> state_of_source{};
  state_of_source.fill(-1);
  const auto states = static_cast<int>(ground_echoes.size());
  for (int round = 0; round < std::min(candidate_count, states); ++round) {
    int best_source = -1;
    int best_state = -1;
    double best_alignment = -2.0;
    for (int s = 0; s < candidate_count; ++s) {
      if (state_of_source[static_cast<std::size_t>(s)] >= 0) continue;
      const Eigen::Vector3d& direction =
          candidates[static_cast<std::size_t>(s)].solution.direction_site;
      for (int e = 0; e < states; ++e) {
        const double alignment = ground_echoes[static_cast<std::size_t>(e)].alignment(direction);
        if (!state_taken[static_cast<std::size_t>(e)] && alignment > best_alignment) {
          best_alignment = alignment;
          best_source = s;
          best_state = e;
        }
      }
    }
    state_taken[static_cast<std::size_t>(best_state)] = true;
    state_of_source[static_cast<std::size_t>(best_source)] = best_state;
  }
  for (int s = 0; s < candidate_count; ++s)
    if (const int e = state_of_source[static_cast<std::size_t>(s)]; e >= 0)
      remove_ground_echo(s, ground_echoes[static_cast<std::size_t>(e)]);
}

void NodePipeline::Impl::remove_ground_echo(int source, GroundEcho& echo) {
  const Eigen::Vector3d direction =
      candidates[static_cast<std::size_t>(source)].solution.direction_site;
  // The search reads this source's bins: the frame's, minus the other sources' (when there
  // are others: their bins found on the remade phasors).
  const bool others = candidate_count > 1;
  if (others && echo.search_due(direction)) only_bins_of(source);
  if (!echo.observe(gcc, direction, others ? gcc.bin_keep() : gcc.saved_bin_keep())) return;
  echo.remove(gcc, direction);
  remeasure(source, true);
  echo.restore(gcc);
}

// A source was measured with every other source's bins in its correlation (the first), or on a
// look made for another (SRP): measured again without the others' bins (their lobes no longer
// pull its peaks), near its own TDOAs.
void NodePipeline::Impl::remeasure(int source, bool near_known_lags) {
  only_bins_of(source, true);
  if (near_known_lags)
    gcc.prepare_phasors();
  else
    gcc.correlate(false);
  Candidate& candidate = candidates[static_cast<std::size_t>(source)];
  std::array<PairTdoa, kMaxPairs> remeasured{};
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairTdoa& before = candidate.tdoas[static_cast<std::size_t>(p)];
    GccPeak peak;
    const bool found = near_known_lags ? gcc.refine_from(p, before.tdoa_s, peak)
                                       : gcc.refine(p, before.tdoa_s, peak);
    if (before.variance_s2 > 0.0 && found && peak.value > 0.0)
      remeasured[static_cast<std::size_t>(p)] = {peak.lag_s, gcc.tdoa_variance_for_peak(peak.value),
                                                 peak.value, peak.coherence};
  }
  const std::span<const PairTdoa> again(remeasured.data(), tdoas.size());
  const DoaSolution solution = solver.solve(again);
  if (!solution.accepted) return;
  candidate.solution = solution;
  std::copy(again.begin(), again.end(), candidate.tdoas.begin());
}

// Drops the bins a found source owns and correlates what is left (the frame's earlier
// correlation values, already used, are overwritten).
void NodePipeline::Impl::mask_source(std::span<const PairTdoa> source_tdoas, bool null_observes) {
  bin_mask.drop(gcc, source_tdoas);
  // Further looks in plain PHAT: the SNR weights favour the first source's bins, and SRP's
  // noise floor is calibrated on equal weights. Refined peaks only when the static null
  // observes this look (SRP refines where it asks, the same answers).
  gcc.correlate(null_observes, false);
  if (null_observes) null_observe();
}

// Replaces this frame's per-frame candidates by every tracked source's smoothed estimate for
// the frame output_delay_s() back.
void NodePipeline::Impl::smooth_candidates(double time_s) {
  for (int s = 0; s < candidate_count; ++s) {
    const Candidate& candidate = candidates[static_cast<std::size_t>(s)];
    observations[static_cast<std::size_t>(s)] = {
        candidate.solution.direction_site,
        std::span<const PairTdoa>(candidate.tdoas.data(), tdoas.size())};
  }
  const int estimate_count = source_tracks->update(
      time_s, std::span<const SourceObservation>(observations.data(), candidate_count), estimates);
  if (acoustic_due) {
    int count = 0;
    for (int slot = 0; slot < source_tracks->slot_count() && count < kMaxSources; ++slot) {
      const int observation = source_tracks->observation_of(slot);
      if (observation < 0) continue;
      acoustic_directions[static_cast<std::size_t>(count)] =
          candidates[static_cast<std::size_t>(observation)].solution.direction_site;
      acoustic_slots[static_cast<std::size_t>(count)] = slot;
      acoustic_generations[static_cast<std::size_t>(count)] = source_tracks->generation(slot);
      ++count;
    }
    measure_acoustics(count);
  }
  candidate_count = 0;
  for (int e = 0; e < estimate_count && candidate_count < params.max_sources; ++e) {
    const SourceEstimate& estimate = estimates[static_cast<std::size_t>(e)];
    const std::span<const PairTdoa> smoothed(estimate.tdoas.data(), tdoas.size());
    Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
    candidate.solution = solver.solve(smoothed);
    if (!candidate.solution.accepted) continue;
    // Two tracks that followed one source: the stronger speaks for it.
    if (already_found(candidate.solution.direction_site)) continue;
    std::copy(smoothed.begin(), smoothed.end(), candidate.tdoas.begin());
    candidate.coherence = mean_coherence(smoothed);
    candidate.time_offset_s = source_tracks->output_delay_s();
    candidate.slot = estimate.track;
    ++candidate_count;
  }
}

void NodePipeline::Impl::measure_acoustics(int count) {
  const auto n = static_cast<std::size_t>(count);
  acoustic->analyse(fft, std::span<const Eigen::Vector3d>(acoustic_directions.data(), n),
                    std::span<const int>(acoustic_slots.data(), n),
                    std::span<const std::uint32_t>(acoustic_generations.data(), n));
}

bool NodePipeline::Impl::was_detecting(double time_s) const {
  const double half_hop_s = 0.5 * hop / sample_rate_hz;
  for (const FrameDetection& frame : recent_detections)
    if (std::abs(frame.time_s - time_s) < half_hop_s) return frame.detecting;
  return false;
}

void NodePipeline::Impl::analyse(const FrameView& frame, std::vector<DoaMeasurement>& out) {
  ++diagnostics.frames_processed;
  const double time_s =
      (static_cast<double>(frame.first_sample) + 0.5 * (frame.length - 1)) / sample_rate_hz;
  diagnostics.level_dbfs = 10.0 * std::log10(std::max(frame.recent_mean_square, 1e-20));

  fft.process(frame);
  gcc.whiten(fft);
  if (snr_weight) snr_weight->update(fft, gcc.bin_weight());
  if (static_null) static_null->mask(time_s, gcc);
  const bool frame_clean =
      frame.non_finite_samples == 0 &&
      frame.clipped_samples <= static_cast<int>(params.max_clipped_fraction * frame.length);
  null_wanted =
      static_null && snr_weight && diagnostics.frames_processed % kStaticNullLookFrames == 0;
  null_observed = false;
  null_time_s = time_s;
  null_frame_clean = frame_clean;
  if (null_wanted) gcc.save_whitened();  // for null_own_look()
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
  // Sharp correlations on a clean frame: worth tracking and solving. Whether to publish also
  // needs the level over the noise floor, whose update needs the coherent power of every
  // source found, so the gate comes after the candidates.
  const bool sharp = detection.frame_clean && detection.mean_peak_value >= params.min_gcc_peak &&
                     detection.inband_power > 0.0;
  if (static_null && !snr_weight) {
    static_null->observe(time_s, gcc, sharp);
    diagnostics.static_sources_nulled = static_null->nulled_count();
  }
  tracker->update(time_s, gcc, sharp, tdoas);
  candidate_count = 0;
  acoustic_due = acoustic && acoustic->due(diagnostics.frames_processed);
  if (sharp) find_candidates();
  // Sources this frame's looks found (before the regression replaces them); none accepted on
  // a sharp frame is still one source for the health checks: a skewed channel makes its
  // delays fail the solver's fit.
  const int frame_sources = candidate_count;
  if (null_wanted && !null_observed) null_own_look();
  double coherent_share = 0.0;
  for (int s = 0; s < candidate_count; ++s)
    coherent_share += candidates[static_cast<std::size_t>(s)].coherence;
  if (candidate_count == 0) coherent_share = coherence_sum / gcc.pair_count();
  detection.mean_coherence = std::min(coherent_share, 0.999);
  const bool detecting = gate.update(detection);
  diagnostics.noise_floor_dbfs = gate.noise_floor_dbfs();
  diagnostics.snr_db = gate.snr_db();
  diagnostics.detecting = detecting;
  array_health.observe(
      time_s,
      std::span<const double>(channel_power.data(), static_cast<std::size_t>(fft.channels())),
      std::span<const PairPeak>(health_pairs.data(), static_cast<std::size_t>(gcc.pair_count())),
      frame_clean && (gate.snr_db() >= params.detection_snr_db || sharp_either_sign()),
      sharp && frame_sources <= 1);
  recent_detections[next_detection] = {time_s, detecting};
  next_detection = (next_detection + 1) % recent_detections.size();
  if (source_tracks) {
    smooth_candidates(time_s);
    // The estimates are for an earlier frame: that frame's gate decides.
    if (candidate_count > 0 && !was_detecting(time_s - source_tracks->output_delay_s())) return;
  } else {
    // The per-pair trackers' sources have no identity over frames but their rank.
    for (int s = 0; s < candidate_count; ++s) {
      Candidate& candidate = candidates[static_cast<std::size_t>(s)];
      candidate.slot = s;
      acoustic_directions[static_cast<std::size_t>(s)] = candidate.solution.direction_site;
      acoustic_slots[static_cast<std::size_t>(s)] = s;
      acoustic_generations[static_cast<std::size_t>(s)] = 0;
    }
    if (acoustic_due) measure_acoustics(candidate_count);
    if (!detecting) return;
  }
  for (int s = 0; s < candidate_count; ++s) {
    const Candidate& candidate = candidates[static_cast<std::size_t>(s)];
    publish(candidate, time_s - candidate.time_offset_s, s, out);
  }
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
  // Counted on the samples as they came; the framer replaces the non-finite ones by 0.
  impl.health.scan(block);
  impl.array_health.clear_events();
  impl.framer.push(block, [&](const FrameView& frame) { impl.analyse(frame, out); });
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
