#pragma once
// The measurement model the calibration fits, written once for doubles and for Ceres' Jets.
//
// A mic's site position: m_i = position + delta_position + R(yaw, pitch, roll) (mic_i + delta_i),
// R = Rz(yaw) Ry(pitch) Rx(roll) (doa/pose_sample.hpp). Channel i hears the sound that left the
// source at t_e at t_e + |p(t_e) - m_i| / c + d_i (d_i: the channel's delay), so the pair delay
// the GCC measures is
//   tau_ij = (|p - m_i| - |p - m_j|) / c + d_i - d_j          (pairs i < j, lexicographic)
// Spherical fronts, not plane waves: a calibration flight passes close to the arrays.
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

}  // namespace dronetrack::calib
