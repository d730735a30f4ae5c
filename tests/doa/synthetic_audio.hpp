#pragma once
// Test signals from physics: band-limited noise delayed exactly in the FFT domain (a circular
// signal whose spectrum is multiplied by e^{-j w t}: an exact fractional delay), mixed with
// independent sensor noise at a chosen in-band SNR. Far-field plane waves from a direction.
#include <fftw3.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "doa/array_geometry.hpp"
#include "doa/audio_block.hpp"
#include "doa/doa_measurement.hpp"
#include "doa/gcc_phat.hpp"

namespace dronetrack::doa::testing {

// A band-limited noise source: random complex spectrum inside [low_hz, high_hz].
class BandNoise {
 public:
  BandNoise(int length, double sample_rate_hz, double low_hz, double high_hz, unsigned seed)
      : length_(length), sample_rate_hz_(sample_rate_hz), spectrum_(length / 2 + 1) {
    std::mt19937 random(seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (int k = 0; k <= length / 2; ++k) {
      const double frequency = k * sample_rate_hz / length;
      if (frequency >= low_hz && frequency <= high_hz)
        spectrum_[k] = {normal(random), normal(random)};
    }
  }
  // A rotor-like comb instead: lines at multiples of fundamental_hz within [low_hz, high_hz]
  // (each on the nearest bin of the whole signal), random phases, -3 dB per octave.
  static BandNoise comb(int length, double sample_rate_hz, double fundamental_hz, double low_hz,
                        double high_hz, unsigned seed) {
    BandNoise source(length, sample_rate_hz, 1.0, 0.0, seed);  // empty band: no noise bins
    std::mt19937 random(seed);
    std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
    for (int h = 1; h * fundamental_hz <= high_hz; ++h) {
      if (h * fundamental_hz < low_hz) continue;
      const auto k =
          static_cast<std::size_t>(std::lround(h * fundamental_hz * length / sample_rate_hz));
      if (k < source.spectrum_.size())
        source.spectrum_[k] = std::polar(std::pow(static_cast<double>(h), -0.5), phase(random));
    }
    return source;
  }
  // The source delayed by `delay_s` (circularly), scaled to RMS `rms`.
  std::vector<double> delayed(double delay_s, double rms) const {
    std::vector<std::complex<double>> shifted(spectrum_.size());
    for (std::size_t k = 0; k < spectrum_.size(); ++k) {
      const double omega =
          2.0 * std::numbers::pi * static_cast<double>(k) * sample_rate_hz_ / length_;
      shifted[k] = spectrum_[k] * std::polar(1.0, -omega * delay_s);
    }
    std::vector<double> out(static_cast<std::size_t>(length_));
    fftw_plan plan = fftw_plan_dft_c2r_1d(length_, reinterpret_cast<fftw_complex*>(shifted.data()),
                                          out.data(), FFTW_ESTIMATE);
    fftw_execute(plan);
    fftw_destroy_plan(plan);
    double sum = 0.0;
    for (const double value : out) sum += value * value;
    const double scale = rms / std::sqrt(sum / length_);
    for (double& value : out) value *= scale;
    return out;
  }

 private:
  int length_;
  double sample_rate_hz_;
  std::vector<std::complex<double>> spectrum_;
};

// Arrival-time offsets (s) of a far-field plane wave from `direction_site` at each mic,
// relative to the array centre: t_i = -u^T (p_i - centre) / c.
inline std::vector<double> plane_wave_delays(const ArrayGeometry& geometry,
                                             const Eigen::Vector3d& direction_site,
                                             double speed_of_sound_mps) {
  std::vector<double> delays;
  const Eigen::Vector3d centre = geometry.centre_site_m();
  for (std::size_t mic = 0; mic < geometry.mic_count(); ++mic)
    delays.push_back(-direction_site.dot(geometry.mic_site_m(mic) - centre) / speed_of_sound_mps);
  return delays;
}

// Interleaved multichannel audio.
struct Recording {
  int channels = 0;
  std::vector<float> interleaved;
  std::size_t frames() const { return interleaved.size() / static_cast<std::size_t>(channels); }
  AudioBlockView view(std::size_t first, std::size_t count) const {
    return {static_cast<std::int64_t>(first), channels, count,
            interleaved.data() + first * static_cast<std::size_t>(channels)};
  }
  void add(int channel, const std::vector<double>& samples) {
    for (std::size_t n = 0; n < frames() && n < samples.size(); ++n)
      interleaved[n * static_cast<std::size_t>(channels) + static_cast<std::size_t>(channel)] +=
          static_cast<float>(samples[n]);
  }
};

inline Recording silent_recording(int channels, std::size_t frames) {
  Recording recording;
  recording.channels = channels;
  recording.interleaved.assign(frames * static_cast<std::size_t>(channels), 0.0F);
  return recording;
}

// Adds a plane-wave source of band noise (RMS `rms`) from `direction_site`.
inline void add_source(Recording& recording, const ArrayGeometry& geometry,
                       const Eigen::Vector3d& direction_site, const BandNoise& source, double rms,
                       double speed_of_sound_mps = 343.0) {
  const std::vector<double> delays =
      plane_wave_delays(geometry, direction_site, speed_of_sound_mps);
  for (int mic = 0; mic < recording.channels; ++mic)
    recording.add(mic, source.delayed(delays[static_cast<std::size_t>(mic)], rms));
}

// Adds independent noise to each channel: band noise in [low, high] at RMS `rms`.
inline void add_sensor_noise(Recording& recording, double sample_rate_hz, double low_hz,
                             double high_hz, double rms, unsigned seed) {
  for (int mic = 0; mic < recording.channels; ++mic) {
    const BandNoise noise(static_cast<int>(recording.frames()), sample_rate_hz, low_hz, high_hz,
                          seed + 7919U * static_cast<unsigned>(mic + 1));
    recording.add(mic, noise.delayed(0.0, rms));
  }
}

// Every mic pair (i < j) with its physical lag limit |p_i - p_j| / c.
inline std::vector<MicPairSpec> all_pairs(const ArrayGeometry& geometry,
                                          double speed_of_sound_mps = 343.0) {
  std::vector<MicPairSpec> pairs;
  for (int i = 0; i < static_cast<int>(geometry.mic_count()); ++i)
    for (int j = i + 1; j < static_cast<int>(geometry.mic_count()); ++j)
      pairs.push_back({i, j,
                       (geometry.mics_m[static_cast<std::size_t>(i)] -
                        geometry.mics_m[static_cast<std::size_t>(j)])
                               .norm() /
                           speed_of_sound_mps});
  return pairs;
}

// Frames (hop_s apart, centred from 0) in [from_s, to_s] with a DOA within `within_deg` of
// `direction_site`: {found, frames}.
inline std::pair<int, int> frames_found(const std::vector<DoaMeasurement>& doas,
                                        const Eigen::Vector3d& direction_site, double within_deg,
                                        double from_s, double to_s, double hop_s) {
  const auto count = static_cast<std::size_t>(std::lround(to_s / hop_s)) + 1;
  std::vector<bool> found(count, false);
  for (const DoaMeasurement& doa : doas) {
    if (doa.time_s < from_s || angle_between_deg(doa.direction, direction_site) > within_deg)
      continue;
    const auto frame = static_cast<std::size_t>(std::lround(doa.time_s / hop_s));
    if (frame < count) found[frame] = true;
  }
  int frames = 0;
  int hits = 0;
  for (std::size_t f = 0; f < count; ++f) {
    const double time_s = static_cast<double>(f) * hop_s;
    if (time_s < from_s || time_s > to_s) continue;
    ++frames;
    hits += found[f] ? 1 : 0;
  }
  return {hits, frames};
}

inline ArrayGeometry tetrahedron(double yaw_deg = 0.0, const std::string& id = "A1") {
  ArrayGeometry geometry;
  geometry.id = id;
  geometry.position_m = {0.0, 0.0, 1.5};
  geometry.yaw_deg = yaw_deg;
  geometry.mics_m = {
      {0, 0, 0.5}, {0.4714, 0.0, -0.1667}, {-0.2357, 0.4082, -0.1667}, {-0.2357, -0.4082, -0.1667}};
  return geometry;
}

}  // namespace dronetrack::doa::testing
