#pragma once
// Detection gate (seed 000's energy gate, plus GCC sharpness): publish a DOA only when the
// in-band level stands above an adaptive noise floor and the correlation peaks are sharp.
// The floor follows the incoherent part of the in-band power, (1 - coherence) * level, so a
// drone that is audible from the first frame does not become the "noise": the floor falls fast
// and rises slowly (rate-limited), like a minimum-statistics tracker.
namespace dronetrack::doa {

struct DetectionSettings {
  double detection_snr_db = 6.0;
  double min_peak_value = 0.2;       // mean normalised GCC-PHAT peak over the pairs
  double floor_rise_db_per_s = 3.0;  // how fast the floor may follow a louder background
  double floor_fall_fraction = 0.5;  // per frame, towards a quieter background
  double silence_dbfs = -130.0;      // below this in-band level: digital silence
};

struct DetectionInput {
  double inband_power = 0.0;     // mean square per sample, in band, mean over channels
  double mean_coherence = 0.0;   // 0..1, coherent share of the in-band power
  double mean_peak_value = 0.0;  // 0..1
  bool frame_clean = true;       // no NaN/Inf, little clipping
};

class DetectionGate {
 public:
  DetectionGate(const DetectionSettings& settings, double hop_s);
  // One frame; returns whether it is detecting.
  bool update(const DetectionInput& input);
  double level_dbfs() const { return level_dbfs_; }
  double noise_floor_dbfs() const { return floor_dbfs_; }
  double snr_db() const { return snr_db_; }
  bool detecting() const { return detecting_; }

 private:
  DetectionSettings settings_;
  double max_rise_db_per_frame_;
  bool has_floor_ = false;
  double level_dbfs_ = -200.0;
  double floor_dbfs_ = -200.0;
  double snr_db_ = -60.0;
  bool detecting_ = false;
};

}  // namespace dronetrack::doa
