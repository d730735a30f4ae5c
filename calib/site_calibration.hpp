#pragma once
// Site calibration from a flight with known positions (issue 16): one weighted nonlinear
// least-squares problem over every array's measured pair delays (TDOAs) against the reference
// track, solved with Ceres. Unknowns, each with a Gaussian prior that is a residual block:
//   per array   yaw/pitch/roll and position offset,
//   per mic     position offset in the array frame (prior std: the array's mic_position_std_m),
//   per channel delay relative to channel 0 (the common part is the node's clock),
//   per node    clock offset (recording clock - reference clock),
//   per reference sample  its true position (prior: the logged fix, std position_std_m).
// TDOA residuals pass a Huber loss; the emission-time delay is in the model. Standard
// deviations come from ceres::Covariance; a parameter whose posterior std is not clearly below
// its prior std was not excited by the flight and is reported so.
#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/reference_track.hpp"

namespace dronetrack::calib {

// An array as configured: the nominal values the calibration corrects.
struct ArrayNominal {
  std::string id;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  // site frame (array origin)
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
  std::vector<Eigen::Vector3d> mics_m;  // array frame
  double mic_position_std_m = 0.0;      // prior std of each mic coordinate; 0 holds them fixed
  // Corrections the nodes already applied to the frames (an earlier calibration): the estimates
  // add to them.
  std::vector<double> channel_delay_s;  // per mic; empty: none
  double clock_offset_s = 0.0;
  double ground_height_m = 0.0;  // site z of the reflecting ground under the array
};

// One analysis frame's pair delays from one array.
struct TdoaFrame {
  int array = 0;               // index into the arrays
  double time_s = 0.0;         // frame centre on that array's recording clock
  std::vector<double> tdoa_s;  // t_i - t_j for mic pairs i < j in lexicographic order
};

// 1-sigma priors: how far each unknown may be from its nominal value before the flight.
struct CalibrationPriors {
  double attitude_std_deg = 3.0;       // yaw, pitch and roll of each array
  double array_position_std_m = 0.05;  // each array's position
  double channel_delay_std_s = 1e-3;   // each channel's delay relative to channel 0
  double clock_offset_std_s = 0.05;    // each node's clock against the reference clock
  // Each array's ground-echo pull (calib/tdoa_model.hpp), prior mean 0: how much the ground
  // image's correlation peak drags the GCC's, per unit of its pull function.
  double ground_echo_pull_std = 0.5;
};

struct CalibrationSettings {
  CalibrationPriors priors;
  double speed_of_sound_mps = 343.0;
  double reference_position_std_m = 1.0;  // the reference log's stated position std
  double reference_max_gap_s = 1.0;       // no interpolation across longer gaps
  // The TDOA noise std; 0: estimated from the residuals (median absolute deviation).
  double tdoa_std_s = 0.0;
  // Whitened TDOA residuals beyond this many std count linearly (Huber), so a frame's wrong
  // peak cannot drag the fit.
  double huber_threshold = 2.0;
  // Between passes a frame with any residual beyond this many std is set aside (a wrong GCC
  // peak); the early passes use a Cauchy loss of the same scale.
  double outlier_threshold = 5.0;
  // A parameter is "excited" when its posterior std is below this share of its prior std.
  double excited_ratio = 0.8;
  // Refused below this many directions (per array) at least min_direction_separation_deg apart:
  // the attitude needs two directions, a mic offset a third.
  int min_distinct_directions = 3;
  double min_direction_separation_deg = 10.0;
  // The GCC's bands (low, high Hz): they shape the ground echo's pull on the measured peaks.
  // Empty: the echo is not modelled.
  std::vector<std::array<double, 2>> bands_hz;
};

// One scalar unknown: nominal (prior mean), estimate and both standard deviations.
struct Estimate {
  double nominal = 0.0;
  double value = 0.0;
  double std = 0.0;        // posterior
  double prior_std = 0.0;  // 0: held fixed
  bool excited = false;    // std < excited_ratio * prior_std
};

struct ResidualStats {
  int count = 0;
  double rms_s = 0.0;
  double median_abs_s = 0.0;
};

struct ArrayCalibration {
  std::string id;
  Estimate yaw_deg, pitch_deg, roll_deg;
  std::array<Estimate, 3> position_m;                   // site frame
  std::vector<std::array<Estimate, 3>> mic_position_m;  // array frame, per mic
  // Per mic, incl. the nominal (the corrections the nodes already applied); mic 0 is the
  // reference (0).
  std::vector<Estimate> channel_delay_s;
  Estimate clock_offset_s;    // incl. the nominal
  Estimate ground_echo_pull;  // the ground image's weight on the GCC peak (0 when not modelled)
  // Per mic, relative to the channels' mean: from levels (calib/channel_gains.hpp), filled by
  // the caller that has them; empty otherwise.
  std::vector<Estimate> channel_gain_db;
  int frames = 0;  // frames used
  int distinct_directions = 0;
  ResidualStats before;     // nominal geometry against the logged positions
  ResidualStats after;      // calibrated geometry against the estimated positions
  ArrayNominal calibrated;  // the nominal with every estimate applied
};

struct CalibrationResult {
  std::vector<ArrayCalibration> arrays;
  double tdoa_std_s = 0.0;  // used for the weights (given or estimated)
  bool tdoa_std_estimated = false;
  // A node's TDOAs are smoothed over neighbouring frames, so their errors are not independent:
  // 1 + 2 sum of the residuals' significant autocorrelations (1: independent frames). The
  // final solve weighs the TDOAs by tdoa_std * sqrt(this).
  double correlation_inflation = 1.0;
  int frames_used = 0;
  int frames_off_reference = 0;  // emission time outside the reference track (or in a gap)
  int frames_rejected = 0;       // set aside as outliers (beyond outlier_threshold std)
  int reference_samples_used = 0;
  ResidualStats before, after;
  std::string solver_report;  // Ceres' one-line summary of the last solve
};

// Input the data cannot support: no frame over the reference, too few directions, non-finite
// values. One line, naming what is missing.
struct CalibrationError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// `prior_centres` (optional, one per array): where the priors are centred when not on `arrays`
// (a later pass linearises at the previous pass's estimate, measured by nodes that applied it,
// but its priors stay the configured values, so no pass's drift is taken as known). The
// estimates' `nominal` are then these.
CalibrationResult calibrate_site(const std::vector<ArrayNominal>& arrays,
                                 const std::vector<TdoaFrame>& frames,
                                 const ReferenceTrack& reference,
                                 const CalibrationSettings& settings,
                                 const std::vector<ArrayNominal>* prior_centres = nullptr);

}  // namespace dronetrack::calib
