// NodePipeline's set-up: what a configuration may ask (setup_problem), and the composition of
// the stages, each sized once here.
#include "doa/node_pipeline_impl.hpp"

namespace dronetrack::doa {

namespace node_detail {

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
}  // namespace node_detail

using namespace node_detail;

std::string NodePipeline::setup_problem(const ArrayGeometry& geometry, const DoaParams& params,
                                        double sample_rate_hz, double speed_of_sound_mps) {
  return node_detail::setup_problem(geometry, params, sample_rate_hz, speed_of_sound_mps);
}

// A pair hears the array-health checks' source at the peak the node needs to publish; a skew
// under half a sample is not one a channel can have (a converter's or a buffer's is whole).
ArrayHealthSettings array_health_settings(const DoaParams& params, double sample_rate_hz) {
  ArrayHealthSettings settings;
  settings.coherent_peak = std::clamp(params.min_gcc_peak, 0.05, 0.95);
  settings.min_skew_us = 0.5e6 / sample_rate_hz;
  return settings;
}

NodePipeline::Impl::Impl(ArrayGeometry geometry_in, int array_index_in, const DoaParams& params_in,
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
                   array_health_settings(params, sample_rate_hz_in)) {
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
  if (static_null && params.static_null_cancel) {
    StaticCancelSettings cancel_settings{tracker_settings.hop_s, params.static_null_learn_s};
    cancel_settings.refill_plane_wave = params.static_null_cancel_refill;
    cancel_settings.min_residual_over_noise = params.static_null_cancel_min_residual_over_noise;
    static_cancel = std::make_unique<StaticSourceCancel>(gcc, cancel_settings);
  }
  if (params.snr_weighting)
    snr_weight =
        std::make_unique<BinSnrWeight>(gcc.band(), tracker_settings.hop_s,
                                       params.snr_noise_rise_db_per_s, params.snr_weight_floor);
  if (params.acoustic.enabled)
    acoustic = std::make_unique<AcousticFeatureExtractor>(geometry, fft.fft_size(), sample_rate_hz,
                                                          speed_of_sound_mps,
                                                          tracker_settings.hop_s, params.acoustic);
  // A two-mic array publishes its GCC's strongest peaks as cone angles (seed 004).
  if (solver.rank() == 1) {
    gcc.set_peak_count(kMaxConePeaks);
    cone_peaks = std::make_unique<ConePeakHistory>(solver, tracker_settings.hop_s);
  }
  if (params.max_sources > 1 && solver.rank() >= 2) {
    srp = std::make_unique<SrpPhat>(solver, gcc, params.srp_grid_deg);
  }
  // Its elevation floor needs up from down: a 3-D array.
  if (params.static_look.enabled && srp && solver.rank() >= 3)
    static_look = std::make_unique<StaticSourceLook>(gcc, tracker_settings.hop_s,
                                                     params.max_sources, params.static_look);
  if (params.own_comb_bins && !gcc.band().empty()) {
    comb_first_bin = gcc.band().front().first_bin;
    const int bins = gcc.band().back().last_bin - comb_first_bin + 1;
    own_comb = std::make_unique<HarmonicCombDetector>(
        comb_first_bin, bins, sample_rate_hz / fft.fft_size(), HarmonicCombSettings{});
    comb_power.assign(static_cast<std::size_t>(bins), 0.0);
    comb_agreement.assign(static_cast<std::size_t>(bins), 0.0);
    comb_lines.assign(static_cast<std::size_t>(bins), 0);
  }
  // The lobe choice judges a look by the lines of the kept bins' comb: it needs the comb
  // detector (own_comb_bins); without it the key does nothing.
  if (params.free_look_lobe_choice && srp && own_comb)
    lobe_lines.assign(static_cast<std::size_t>(gcc.band_bin_count()), LineBin{});
  // A planar or linear array cannot tell the echo (mirrored elevation) from the source, and a
  // horizontal one hears the same comb at every mic: no differential phase to remove.
  if (params.ground_echo && solver.rank() >= 3) {
    GroundEchoSettings echo_settings;
    echo_settings.ground_height_m = params.ground_height_m;
    ground_echoes.assign(static_cast<std::size_t>(params.max_sources),
                         GroundEcho(geometry, gcc, speed_of_sound_mps, echo_settings));
  }
}

}  // namespace dronetrack::doa
