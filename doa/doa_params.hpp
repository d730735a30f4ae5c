#pragma once
// Processing parameters of an array node. Parsed and validated in config/ (parse_doa_params.cpp);
// every field has its unit in the name and a default that works on the bundled scenes.
// docs/doa.md documents every key.
#include <string>
#include <vector>

#include "doa/harmonic_comb.hpp"

namespace dronetrack::doa {

struct FrequencyBand {
  double low_hz = 1500.0;
  double high_hz = 3500.0;
};

// Acoustic evidence per source (doa/acoustic_features.hpp), the "doa.acoustic" config section.
struct AcousticSettings {
  bool enabled = true;
  // Where the comb is looked for (clamped to the spectrum). From 800 Hz: in the seed's 1.5-3.5 kHz
  // a real quadcopter's four rotors' combs smear (tests/doa/harmonic_comb_test.cpp).
  FrequencyBand band_hz{800.0, 3500.0};
  // 0.3 s at the default hop: the features move over seconds, and one analysis of one source
  // costs ~18 us (doa_bench BM_AcousticFeatures), a quarter of the FFT kernel of a frame.
  int analysis_every_frames = 6;
  double comb_memory_s = 1.0;  // time constant of the mean comb autocorrelation
  double history_s = 3.0;      // span of the over-the-last-seconds features
  // A bin is a source's when steering to it makes the mics' phasors this coherent (|sum|^2 over
  // M sum |X|^2: 1 for one plane wave, 1/M for incoherent noise) and no other source's more.
  double min_bin_coherence = 0.5;
  // A comb found on a source's bins is its evidence only when its lines, steered together, peak
  // within this of the source's direction; otherwise they are another source's (one the frame
  // did not find) whose beam overlaps this one's, and are taken out of its spectrum. 4 deg is
  // srp_min_separation_deg's default: two directions closer than that are one source for the
  // node (a site sets 4 to check). 0: no check, the default: with the check the non-drones'
  // tracks are confirmed more often (docs/classification.md "Whose lines").
  double line_direction_tolerance_deg = 0.0;
  HarmonicCombSettings comb;
};

// One more look a frame on the pair phasors averaged over frames, for static sources the
// frame's own looks miss under louder ones (doa/static_source_look.hpp), the "doa.static_look"
// config section. On: no bundled scene loses by it (docs/doa.md "Static look, on / off").
struct StaticLookSettings {
  bool enabled = true;
  // Time constant of the phasors' average: 0.14 s is a = 0.7 per 50 ms hop, the measured
  // prototype's (docs/classification.md): long enough for a static source to gain on a car
  // drifting ~6 deg/s, short enough that a mover's smear leaves its look unheld.
  double averaging_time_s = 0.14;
  double max_drift_deg = 1.0;  // a look's direction this close to one hold_s..2 hold_s earlier
  double hold_s = 1.0;         // how long a direction must stay put to be static
  // A direction the frame's own looks found a source near (srp_min_separation_deg) within this
  // long is theirs and the static look adds nothing there: a drone flying radially holds its
  // direction as well as a hovering one, and still leads the average for about its time
  // constant after the own looks last found it. 0: this frame's sources only (the prototype:
  // perimeter D2 0.84 -> 1.27 m); 0.2 s keeps 0.84 m; 0.3 s halves the hovering drone's gain.
  double own_look_memory_s = 0.2;
  // Lowest elevation reported (a generator and its ground image merge near 0 deg; the static
  // null's domain is up to static_null_max_elevation_deg = 3).
  double min_elevation_deg = 5.0;
  // Looks on the average a frame, at most: a look that lands on a source the own looks
  // explain (or whose direction is not static) has its lobe taken out and the next is made,
  // so a louder neighbour of the hovering drone does not hide it from the look.
  int max_looks = 2;
  // The search over every direction runs every this many frames; a source it holds is measured
  // again every frame near its held direction (no search), and the search runs every frame for
  // this many frames after the held source is lost. 1: the known-answer test's weak source is
  // above the search's floor in a few frames only, and every 4th frame found it 5 times, not 16
  // (doa_static_look_tests).
  int search_every_frames = 1;
};

enum class TdoaTracker { per_frame, bayesian_grid, multi_peak, robust_regression };

// How the GCC peak is refined below the lag grid: maximising the continuous band-limited
// correlation (exact, the default) or a parabola through three full-rate samples.
enum class LagInterpolation { parabolic, band_limited };

struct DoaParams {
  std::vector<FrequencyBand> bands_hz{FrequencyBand{}};  // seed 002: 1.5-3.5 kHz
  // Several bands (issue 15, seed 003: sources separated by band): true runs the whole node once
  // per band (its own detection gate, GCC over that band's bins, TDOA tracker, source search and
  // cones) and publishes each band's sources as their own, source_index = band + bands x rank in
  // the band, each band's lag grid at least correlation_oversample and >= 8 points a period of
  // its centre (docs/doa.md stage 9, "Fringes"); false correlates the union of the bands as one
  // (e.g. a band with a notch). One band: no difference.
  bool per_band_detection = true;
  double frame_s = 0.17;  // analysis frame length; FFT size = next FFTW-friendly size >= frame
  double hop_s = 0.05;    // about 20 DOAs per second
  TdoaTracker tdoa_tracker = TdoaTracker::robust_regression;  // best on the scenes (docs/doa.md)
  // Sources per frame (SRP-PHAT peaks, each on the bins the louder ones leave): a capacity, not
  // a design. The search stops at the first look under the detection floor, so a quiet site
  // pays for one failed look; a site with a generator, a road and an aircraft besides two drones
  // needs all of them (issue 14): six sources there, and with 4 the drone the others outshout
  // at an array lost its frames to the budget (docs/doa.md "The remaining misses", session 19).
  // Cost per source: docs/doa.md.
  int max_sources = 6;
  double detection_snr_db = 0.0;  // in-band level over the adaptive noise floor to publish

  // Added with the DSP (issue 4); all optional keys of the "doa" config section.
  double min_gcc_peak = 0.2;  // mean normalised GCC-PHAT peak over pairs needed to publish
  double noise_floor_rise_db_per_s = 3.0;  // adaptive floor: how fast it follows louder noise
  double max_clipped_fraction = 0.01;      // frames with more clipped samples give no DOA
  LagInterpolation lag_interpolation = LagInterpolation::band_limited;
  int correlation_oversample = 1;       // lag grid: 2x the band's Nyquist rate, times this
  double max_angular_rate_dps = 90.0;   // trackers: largest plausible DOA rate of a source
  int regression_window_frames = 13;    // robust_regression: frames in the sliding window
  int regression_delay_frames = 6;      // robust_regression: evaluate the fit this many frames
                                        // back (6 = the window's centre; adds 6 hops latency)
  double max_norm_error = 0.1;          // LS: reject when ||A^-1 b| - 1| exceeds this
  double max_chi2_per_dof = 30.0;       // LS: reject when the TDOA fit residual exceeds this
  double srp_grid_deg = 5.0;            // SRP-PHAT direction grid spacing
  double srp_min_separation_deg = 4.0;  // two sources closer than this are one
  // A further source (after the louder ones' bins are dropped) needs an SRP power this many
  // standard deviations above that of incoherent noise (which follows from the bins and frame).
  double srp_min_power_sigmas = 4.0;
  // Horizon mask (site frame, from the array): anything lower is a ground source or the
  // ground's mirror image of a drone, never reported. A drone below the array's own height at
  // close range (rare) is lower; lower it for arrays on masts or roofs.
  double min_elevation_deg = -3.0;

  // Per-bin SNR weighting of the first source's PHAT phasors (doa/bin_snr_weight.hpp): bins
  // with only noise fade out of its correlation. Off: plain PHAT.
  bool snr_weighting = true;
  double snr_noise_rise_db_per_s = 1.0;  // how fast a bin's noise estimate follows louder noise
  // Least weight of a bin: minimum tracking cannot see the noise under a source that never goes
  // quiet in a bin, so no bin is trusted to be pure noise (seed 002 at 10 dB: A1 median 0.224
  // deg at 0.15, 0.209 at 0.3, 0.199 at 0.5, plain PHAT 0.200; 0 dB far pass: see docs/doa.md).
  double snr_weight_floor = 0.3;

  // Ground reflection removal (doa/ground_echo.hpp), 3-D arrays: each source's echo off the
  // ground under the array (its range and the ground's reflection coefficient searched and
  // followed) is divided out of the mics' phases and its TDOAs measured again. Off: the echo pulls
  // the elevation by a few tenths of a degree (seed-002 scene: A1's median 0.18 -> 0.10 deg).
  bool ground_echo = true;
  double ground_height_m = 0.0;  // site z of the reflecting ground (flat) under the arrays

  // docs/doa.md stage 7c, measured: when a frame has several sources, a source with a harmonic
  // comb (a rotor) is measured again on its comb's lines and the bins it owns; the other bins
  // between its lines carry the others' broadband and lines, which pull its peaks. On: every
  // mixed-site and perimeter figure gains (5-20 % lower drone RMSE); a lone low-SNR drone whose
  // frames turn multi-source through strays loses 1-2 % (far low-SNR pass 3.03 -> 3.08 m).
  bool own_comb_bins = true;

  // docs/doa.md stage 7d, measured: with robust_regression, each source the node tracks and a
  // frame has not found yet is measured from its track's lags (the fringe it was on) before the
  // free SRP looks, so a drone whose own bins are only its rotor's lines is not taken one
  // carrier fringe off (the mixed site's hovering drone 11 deg low at N1). Off by default: the
  // drones' DOA coverage rises on every multi-source scene, but the perimeter's fused tracks
  // gain false-track time (0 -> 2.1 %) and the far low-SNR pass 0.10 m of RMSE.
  bool follow_source_tracks = false;

  // docs/doa.md stage 7, "A free look's lobe": a free SRP look on a source left with only its
  // rotor's lines may take a neighbouring carrier fringe (one period off at one mic); the look
  // and those neighbours are judged by how well they align the lines of the kept bins' comb,
  // each line bin counted the same, and the best is kept. Off by default: 27 -> 40 of 53 frames
  // on the known-answer scene, +1.1 % of the mixed site's drone frames and +4.5 % of the
  // two-source bench frame's instructions, but the mixed site's D2 RMSE 1.86 -> 1.93 m.
  bool free_look_lobe_choice = false;

  // docs/doa.md stage 7, "The comb look": when the free search stops under the SRP floor, one
  // more look on the kept bins of the harmonic comb those bins' power shows (a rotor's lines,
  // chosen by power, not by phase), against the floor for that many lines. A comb whose lines
  // stand over their noise sums too few bins to clear the floor set for the whole band.
  bool comb_look = true;

  // Static-source null (doa/static_source_null.hpp): sources that stay put at or below the
  // horizon are learned from their constant TDOAs and their band bins dropped before the
  // inverse FFTs, so a drone next to a loud ground source is still found.
  bool static_null = true;
  double static_null_learn_s = 3.0;            // stays put this long before it is nulled
  double static_null_forget_s = 2.0;           // not heard this long: forgotten
  double static_null_max_elevation_deg = 3.0;  // never null anything higher (hovering drones)
  double static_null_tolerance_us = 20.0;      // per pair: "the same TDOA" from frame to frame
  int static_null_max_sources = 2;             // nulled at once
  // docs/doa.md stage 3c: the nulled sources' bins kept with the source projected out of each
  // bin's mic vector (its learned steering vector), instead of dropped: a drone under the
  // generator in its own comb bins keeps them (ground-interferer draws 58-63: track coverage
  // >= 93 % and RMSE 0.61-0.83 m, against 66-98 % and 0.80-2.89 m with the bins dropped).
  bool static_null_cancel = true;
  // docs/doa.md stage 3c, session 24: each cancelled bin's component along the nulled source's
  // steering vector refilled so the bin's mic moduli are equal again (a far source's plane wave),
  // instead of left out: the projection bends every pair's phase.
  bool static_null_cancel_refill = true;
  // docs/doa.md stage 3c: a cancelled bin is kept only where what the projection leaves is at
  // least this many times the share the bin's noise would leave (a ratio of power shares; 2:
  // something else holds at least as much power there as the noise). 0 keeps every bin the
  // 10 % share rule keeps, also on an array far from the generator where only noise is left.
  double static_null_cancel_min_residual_over_noise = 2.0;

  StaticLookSettings static_look;  // issue 14: docs/doa.md stage 7a
  AcousticSettings acoustic;  // features of each source's spectrum for the classifier (issue 14)
};

}  // namespace dronetrack::doa
