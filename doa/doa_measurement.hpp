#pragma once
// One direction of arrival from one array: what the node publishes and the fusion consumes.
// Carries who measured it and how (array id and index, time, covariance) so the fusion builds
// its measurement model from the array pose alone.
#include <array>
#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace dronetrack::doa {

inline constexpr int kMaxPairs = 28;  // 8 mics

// What the geometry can and cannot tell (SPEC 4.2).
enum class DoaAmbiguity : std::uint8_t {
  none = 0,            // full 3-D direction
  mirror_up_down = 1,  // planar array: direction and its mirror through the array plane
  cone = 2,            // two mics: only the angle to the mic axis is known
};

// "none", "mirror_up_down", "cone": the names used in JSON outputs and the HTTP API.
inline const char* to_string(DoaAmbiguity ambiguity) {
  switch (ambiguity) {
    case DoaAmbiguity::none:
      return "none";
    case DoaAmbiguity::mirror_up_down:
      return "mirror_up_down";
    case DoaAmbiguity::cone:
      return "cone";
  }
  return "none";
}

// What the source's own spectrum says (doa/acoustic_features.hpp), for the fusion's classifier.
// The comb figures are from the source's bins in the analysis bands.
struct AcousticFeatures {
  bool valid = false;            // measured (false: no analysis yet, or features off)
  double fundamental_hz = 0.0;   // harmonic comb spacing over the last ~second; 0: no comb
  double comb_strength = 0.0;    // salience autocorrelation at that spacing, 0..1
  int harmonic_count = 0;        // lines on the comb in the latest spectrum
  double broadband_share = 1.0;  // share of the source's band power off the comb's lines, 0..1
  // Over the last seconds of this source (the node's source track):
  double comb_persistence = 0.0;     // share of its analyses with a comb, 0..1
  double fundamental_spread = 0.0;   // relative std of the comb spacing (0.01 = 1 %)
  double level_modulation_db = 0.0;  // std of its in-band level
  double history_s = 0.0;            // the span those figures cover
};

// Where the array was, and how it was turned, at the frame's time (issue 15). A fixed array's
// comes from the site config; a moving array's is interpolated from its pose (pose_file, or the
// ArrayPose DDS topic live) at the frame's centre. The fusion builds its measurement model from
// this stamp alone, so it never needs the pose stream.
struct PoseStamp {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();  // acoustic centre, site frame
  Eigen::Quaterniond array_to_site = Eigen::Quaterniond::Identity();
  bool moving = false;  // from a pose track (false: the config's fixed pose)
};

// Seed 004's multi-peak likelihood keeps the GCC's strongest peaks, not only the largest.
inline constexpr int kMaxConePeaks = 4;

struct DoaMeasurement {
  std::string array_id;
  int array_index = -1;  // index into the site's arrays
  double time_s = 0.0;   // centre of the analysis frame, recording time
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // unit vector, SITE frame
  // Covariance of (azimuth, elevation) in rad^2, propagated from the TDOA noise. The fusion's
  // measurement noise.
  Eigen::Matrix2d azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 1e-4;
  double quality = 0.0;  // 0..1, from GCC peak sharpness and LS residual
  double snr_db = 0.0;   // in-band SNR against the adaptive noise floor
  int source_index = 0;  // 0..K-1 when one frame yields several directions
  DoaAmbiguity ambiguity = DoaAmbiguity::none;
  // What a rank-deficient array measured (SPEC 4.2), site frame:
  //   cone            the angle between ambiguity_axis (unit, from mic 0 towards mic 1) and the
  //                   direction to the source, with its variance; `direction` is only the
  //                   horizontal point of that cone, for display. Nothing downstream may use it as
  //                   a direction.
  //   mirror_up_down  ambiguity_axis is the array plane's unit normal; `direction` is the image on
  //                   the normal's side, its mirror direction - 2 (direction . axis) axis is as
  //                   likely, and azel_covariance_rad2 holds for both.
  Eigen::Vector3d ambiguity_axis = Eigen::Vector3d::UnitZ();
  double cone_angle_rad = 0.0;
  double cone_angle_variance_rad2 = 0.0;
  // Cone only: the GCC's strongest peaks as cone angles, strongest first (peak 0 is the one
  // measured), with their GCC values as weights (seed 004, SPEC 4.3).
  int cone_peak_count = 0;
  std::array<double, kMaxConePeaks> cone_peak_angle_rad{};
  std::array<double, kMaxConePeaks> cone_peak_weight{};
  PoseStamp pose;
  int pair_count = 0;
  std::array<double, kMaxPairs> tdoa_s{};  // per mic pair (i<j in lexicographic order)
  AcousticFeatures acoustic;
};

}  // namespace dronetrack::doa
