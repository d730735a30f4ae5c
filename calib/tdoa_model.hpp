#pragma once
// The measurement model the calibration fits, written once for doubles and for Ceres' Jets.
//
// A mic's site position: m_i = position + delta_position + R(yaw, pitch, roll) (mic_i + delta_i),
// R = Rz(yaw) Ry(pitch) Rx(roll) (doa/pose_sample.hpp). Channel i hears the sound that left the
// source at t_e at t_e + |p(t_e) - m_i| / c + d_i (d_i: the channel's delay), so the pair delay
// the GCC measures is
//   tau_ij = (|p - m_i| - |p - m_j|) / c + d_i - d_j          (pairs i < j, lexicographic)
// Spherical fronts, not plane waves: a calibration flight passes close to the arrays.
#include <array>
#include <cmath>
#include <cstddef>

namespace dronetrack::calib {

// Rz(yaw) Ry(pitch) Rx(roll) applied to `v`, angles in radians.
template <class T>
void rotate_array_to_site(const T& yaw, const T& pitch, const T& roll, const T* v, T* out) {
  using std::cos;
  using std::sin;
  const T cy = cos(yaw), sy = sin(yaw), cp = cos(pitch), sp = sin(pitch), cr = cos(roll),
          sr = sin(roll);
  // Rx(roll)
  const T x1 = v[0];
  const T y1 = cr * v[1] - sr * v[2];
  const T z1 = sr * v[1] + cr * v[2];
  // Ry(pitch)
  const T x2 = cp * x1 + sp * z1;
  const T y2 = y1;
  const T z2 = -sp * x1 + cp * z1;
  // Rz(yaw)
  out[0] = cy * x2 - sy * y2;
  out[1] = sy * x2 + cy * y2;
  out[2] = z2;
}

// Pair delays (s) for a source at `source_m` heard by `mics` site positions (3 per mic) with
// channel delays `delays_s`; writes mics*(mics-1)/2 values.
template <class T>
void predict_tdoas(const T* source_m, const T* mic_site_m, const T* delays_s, std::size_t mics,
                   double speed_of_sound_mps, T* tdoa_s) {
  using std::sqrt;
  std::size_t pair = 0;
  for (std::size_t i = 0; i < mics; ++i) {
    const T* mi = mic_site_m + 3 * i;
    const T ri = sqrt((source_m[0] - mi[0]) * (source_m[0] - mi[0]) +
                      (source_m[1] - mi[1]) * (source_m[1] - mi[1]) +
                      (source_m[2] - mi[2]) * (source_m[2] - mi[2]));
    for (std::size_t j = i + 1; j < mics; ++j) {
      const T* mj = mic_site_m + 3 * j;
      const T rj = sqrt((source_m[0] - mj[0]) * (source_m[0] - mj[0]) +
                        (source_m[1] - mj[1]) * (source_m[1] - mj[1]) +
                        (source_m[2] - mj[2]) * (source_m[2] - mj[2]));
      tdoa_s[pair++] = (ri - rj) / speed_of_sound_mps + delays_s[i] - delays_s[j];
    }
  }
}

// How far a second correlation peak `separation_s` from the first drags the GCC's maximum, per
// unit of its weight relative to the first: R'(separation) / R''(0), R the correlation of a
// whitened source over the bands, R(t) = sum over bands of (sin 2 pi f2 t - sin 2 pi f1 t) / 2 pi
// t. Close peaks merge into their weighted mean (the pull is the separation); peaks a quarter of a
// cycle apart no longer pull; further out the correlation's side lobe pushes. The ground image's
// pair delay differs from the direct sound's by tens of microseconds on the pairs whose mics
// stand at one height, and the measured delays follow this curve (calibration flight with no
// array errors, 40 dB SNR: residual means of +2.9 us at +60 us separation, -2.5 us at -100 us,
// zero at +-180 us; none without the echo).
template <class T>
T peak_pull_s(const T& separation_s, const std::array<double, 2>* bands_hz, std::size_t bands) {
  using std::cos;
  using std::sin;
  constexpr double kTwoPi = 6.283185307179586;
  double curvature = 0.0;  // -R''(0) / (2 pi)^2
  for (std::size_t b = 0; b < bands; ++b)
    curvature += (std::pow(bands_hz[b][1], 3) - std::pow(bands_hz[b][0], 3)) / 3.0;
  if (bands == 0 || curvature <= 0.0) return T(0.0);
  // Below a tenth of a microsecond the closed form cancels; the pull is the separation there.
  if (separation_s < T(1e-7) && separation_s > T(-1e-7)) return separation_s;
  T slope = T(0.0);  // R'(t) (2 pi t^2)
  for (std::size_t b = 0; b < bands; ++b) {
    const double w1 = kTwoPi * bands_hz[b][0], w2 = kTwoPi * bands_hz[b][1];
    slope += (w2 * cos(w2 * separation_s) - w1 * cos(w1 * separation_s)) * separation_s -
             (sin(w2 * separation_s) - sin(w1 * separation_s));
  }
  return slope / (kTwoPi * separation_s * separation_s) / (-kTwoPi * kTwoPi * curvature);
}

}  // namespace dronetrack::calib
