#pragma once
// One direction of arrival from one array: what the node publishes and the fusion consumes.
// Carries who measured it and how (array id and index, time, covariance) so the fusion builds
// its measurement model from the array pose alone.
#include <array>
#include <cstdint>
#include <string>

#include <Eigen/Core>

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
  int pair_count = 0;
  std::array<double, kMaxPairs> tdoa_s{};  // per mic pair (i<j in lexicographic order)
  AcousticFeatures acoustic;
};

}  // namespace dronetrack::doa
