#pragma once
// A simulated scene: the site (SPEC 3.1), how long, how fast it is sampled, what sounds where,
// and the noise. Parsed and validated once (parse_scenario); everything else takes this struct.
// The file format is documented in docs/scenarios.md.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/site_config.hpp"
#include "sim/array_errors.hpp"
#include "sim/array_motion.hpp"
#include "sim/impulsive_noise.hpp"
#include "sim/trajectory.hpp"

namespace dronetrack::sim {

// A harmonic source: a drone's rotor (type "rotor"), and with other defaults a car's or truck's
// engine ("engine"), a generator locked to the mains ("generator"), a light aircraft's propeller
// ("propeller"): harmonics of a slowly wandering fundamental + broadband. docs/scenarios.md.
struct RotorSignal {
  double blade_pass_hz = 160.0;     // fundamental, 80-250 Hz for small multirotors
  double rpm_wander = 0.02;         // peak relative RPM deviation (0.02 = +-2 %)
  double wander_period_s = 6.0;     // typical period of the wander
  int harmonics = 40;               // 30-60; those above 0.4 * sample rate are dropped
  double slope_db_per_octave = -3;  // harmonic amplitude roll-off
  double broadband_db = -10.0;      // broadband power relative to the harmonic power
  // Harmonics above this frequency fall a further rolloff_db_per_octave (an engine's firing
  // harmonics die out above ~1 kHz); 0: no corner.
  double rolloff_corner_hz = 0.0;
  double rolloff_db_per_octave = 0.0;
  double broadband_low_hz = 20.0;  // broadband band (tyres and road: 300-4000 Hz)
  double broadband_high_hz = 0.0;  // 0: up to the band limit
};

// Birdsong-like chirps: short sweeps at random moments, deterministic per seed and source.
struct ChirpsSignal {
  double low_hz = 2000.0;  // each sweep runs between two frequencies drawn in [low, high]
  double high_hz = 6000.0;
  double min_duration_s = 0.05;
  double max_duration_s = 0.3;
  double mean_interval_s = 0.8;  // mean time between chirp starts (exponential)
};

// A real recording, looped (with a short cross-fade) over [start_s, end_s).
struct RecordingSignal {
  std::filesystem::path file;  // absolute
  double start_s = 0.0;
  std::optional<double> end_s;  // default: end of file
};

// Band-limited Gaussian noise (a broadband ground interferer: generator, vehicle, pump).
struct NoiseSignal {
  double low_hz = 100.0;
  double high_hz = 8000.0;
};

// Steady tones (a tonal interferer: transformer hum, fan, alarm).
struct TonesSignal {
  std::vector<double> frequencies_hz;
  std::vector<double> relative_db;  // one per tone; 0 dB each by default
};

enum class SignalType { rotor, recording, noise, tones, chirps };
enum class SourceKind { drone, interferer };

struct SourceSpec {
  std::string id;
  SourceKind kind = SourceKind::drone;
  // What it is, for eval's drone-or-not figures (truth "class"): "drone", "ground" (generator,
  // vehicle, pump), "aircraft", "bird". Default: drone for drones, ground for interferers.
  std::string source_class = "drone";
  double level_db_spl = 85.0;  // RMS sound pressure level at 1 m, dB re 20 uPa
  SignalType signal_type = SignalType::rotor;
  RotorSignal rotor;
  RecordingSignal recording;
  NoiseSignal noise;
  TonesSignal tones;
  ChirpsSignal chirps;
  Trajectory trajectory;
};

// One noise component. Level either as in-band SNR (signal = all drones, band = the site's
// doa.bands_hz) at each array (or at `snr_reference_array` for all arrays), or absolute.
struct NoiseLevel {
  bool enabled = false;
  std::optional<double> snr_db;
  std::optional<double> level_db_spl;  // RMS over the whole band, dB re 20 uPa
};

struct NoiseSpec {
  NoiseLevel sensor;  // white, independent per mic
  NoiseLevel wind;    // low-frequency, gusty, independent per mic
  double wind_corner_hz = 40.0;
  double wind_gust_depth = 0.5;  // relative amplitude modulation
  NoiseLevel ambient;  // diffuse: coherent within an array at low frequency, independent above
  double ambient_coherent_below_hz = 0.0;  // 0: c / (2 * largest mic spacing) of each array
  std::string snr_reference_array;         // empty: every array gets the SNR itself
  ImpulsiveNoise impulsive;                // alpha-stable bursts (sim/impulsive_noise.hpp)
};

// An array that moves (site.arrays[i].trajectory): its motion, and how often its pose file
// (<id>.pose.jsonl, referenced as the array's pose_file in DIR/site.json) has a line.
struct MovingArray {
  ArrayMotion motion;
  double pose_rate_hz = 20.0;
};

// A GPS logger on one source (a calibration flight's reference, docs/calibration.md): its
// positions every 1 / rate_hz s with Gaussian noise of position_std_m, written as
// DIR/reference.jsonl.
struct ReferenceLogSpec {
  bool enabled = false;
  std::string source;  // the source's id
  double rate_hz = 10.0;
  double position_std_m = 1.0;
};

struct Scenario {
  std::filesystem::path file;  // empty if built in memory
  std::string description;
  std::uint64_t seed = 0;
  double sample_rate_hz = 48000.0;
  double duration_s = 10.0;
  double full_scale_db_spl = 120.0;  // sample value 1.0 = this SPL (20 Pa at 120 dB)
  double ground_reflection = 0.0;    // image-source reflection coefficient, 0 = no ground
  config::SiteConfig site;
  nlohmann::json site_json;             // the site section as given, copied into DIR/site.json
  std::vector<double> recording_end_s;  // per array; <= 0: the whole duration
  std::vector<std::optional<MovingArray>> moving_arrays;  // per array; nullopt: fixed
  std::vector<SourceSpec> sources;
  NoiseSpec noise;
  // The arrays as built (issue 16): `site` holds them with these draws applied (rendering and
  // truth), `site_json` the nominal values (site.json).
  ArrayErrorSpec array_error_spec;
  std::vector<ArrayErrors> array_errors;  // per array; all zero when not enabled
  ReferenceLogSpec reference_log;
};

// Validates a scenario document. Throws config::ConfigError with one line per problem, each
// naming its JSON path ("sources[0].trajectory.speed_mps: must be in [0, 200], got -1").
// `base_dir` resolves relative recording paths. Warnings (unknown keys) go to `warnings`.
Scenario parse_scenario(const nlohmann::json& document, const std::filesystem::path& base_dir,
                        std::vector<std::string>& warnings);
Scenario parse_scenario(const nlohmann::json& document, const std::filesystem::path& base_dir);
// Reads a scenario file; problems are prefixed with the file name.
Scenario load_scenario(const std::filesystem::path& file, std::vector<std::string>& warnings);

}  // namespace dronetrack::sim
