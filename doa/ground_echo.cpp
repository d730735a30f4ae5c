#include "doa/ground_echo.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace dronetrack::doa {

namespace {

// Acquisition scans curvature 1/range in these steps: the centre's echo delay moves by at most
// ~0.045 ms per step (5.5 ms m at mid elevations), a fifth of the band centre's period, so the
// scan cannot step over the coherence peak; the local search then refines.
constexpr double kScanStep_per_m = 0.008;
// Local search: curvature and gain steps, and how far one search may move them.
constexpr double kLocalCurvatureStep_per_m = 0.003;
constexpr double kLocalGainStep = 0.1;
constexpr double kAcquisitionGain = 0.5;
constexpr double kMinGain = 0.05;
constexpr double kMaxGain = 0.95;

// Vertex of the parabola through (-step, left), (0, centre), (+step, right), as a multiple of
// step, clamped to [-limit, limit]; 0 when the three do not make a maximum.
double parabola_vertex(double left, double centre, double right, double limit) {
  const double curvature = left - 2.0 * centre + right;
  if (!(curvature < 0.0)) return left > right ? -limit : (right > left ? limit : 0.0);
  return std::clamp(0.5 * (left - right) / curvature, -limit, limit);
}

}  // namespace

GroundEcho::GroundEcho(const ArrayGeometry& geometry, const GccPhat& gcc, double speed_of_sound_mps,
                       GroundEchoSettings settings)
    : settings_(settings),
      speed_of_sound_mps_(speed_of_sound_mps),
      runs_(gcc.band()),
      bin_omega_(gcc.bin_omega_rad_per_s()) {
  const Eigen::Vector3d centre = geometry.centre_site_m();
  centre_height_m_ = centre.z() - settings_.ground_height_m;
  for (std::size_t mic = 0; mic < geometry.mic_count(); ++mic) {
    mics_m_.push_back(geometry.mic_site_m(mic) - centre);
    mic_heights_m_.push_back(geometry.mic_site_m(mic).z() - settings_.ground_height_m);
  }
  const std::size_t mics = mics_m_.size();
  arrival_s_.assign(mics, 0.0);
  delay_s_.assign(mics, 0.0);
  level_.assign(mics, 0.0);
  direct_.assign(mics, {});
  direct_step_.assign(mics, {});
  echo_.assign(mics, {});
  echo_step_.assign(mics, {});
  rotation_.assign(static_cast<std::size_t>(gcc.band_bin_count()), {1.0, 0.0});
  min_sine_elevation_ = std::sin(settings_.min_elevation_deg * std::numbers::pi / 180.0);
  max_jump_cosine_ = std::cos(settings_.max_direction_jump_deg * std::numbers::pi / 180.0);
  reset();
}

void GroundEcho::reset() {
  locked_ = false;
  curvature_per_m_ = 0.0;
  gain_ = 0.0;
  last_direction_.setZero();
  frames_since_search_ = settings_.acquire_every_frames;
}

double GroundEcho::range_m() const {
  return curvature_per_m_ > 0.0 ? 1.0 / curvature_per_m_ : std::numeric_limits<double>::infinity();
}

void GroundEcho::paths(const Eigen::Vector3d& direction_site, double curvature_per_m) {
  for (std::size_t mic = 0; mic < mics_m_.size(); ++mic) {
    const Eigen::Vector3d& offset = mics_m_[mic];
    if (curvature_per_m <= 0.0) {
      // Plane waves: the image's direction is the source's mirrored in the ground, so the
      // reflected path is longer by twice the mic's height times the sine of the elevation.
      arrival_s_[mic] = -direction_site.dot(offset) / speed_of_sound_mps_;
      delay_s_[mic] = 2.0 * direction_site.z() * mic_heights_m_[mic] / speed_of_sound_mps_;
      level_[mic] = 1.0;
      continue;
    }
    const double range_m = 1.0 / curvature_per_m;
    const Eigen::Vector3d source = range_m * direction_site;  // from the centre
    // Mirrored in the ground plane, which lies centre_height_m_ under the centre.
    const Eigen::Vector3d image(source.x(), source.y(), -source.z() - 2.0 * centre_height_m_);
    const double direct_m = (source - offset).norm();
    const double reflected_m = (image - offset).norm();
    arrival_s_[mic] = -direction_site.dot(offset) / speed_of_sound_mps_;
    delay_s_[mic] = (reflected_m - direct_m) / speed_of_sound_mps_;
    level_[mic] = direct_m / reflected_m;  // spherical spreading over the longer path
  }
}

double GroundEcho::coherence(const GccPhat& gcc, double gain) {
  const std::span<const double> weights = gcc.bin_weight();
  const std::span<const std::uint8_t> keep = gcc.bin_keep();
  const std::size_t mics = mics_m_.size();
  double total = 0.0;
  double weight_sum = 0.0;
  std::size_t index = 0;
  for (const BandRun& run : runs_) {
    const double first_omega = run.first_bin * bin_omega_;
    for (std::size_t mic = 0; mic < mics; ++mic) {
      // Units are aligned on the direct path by e^{+j w t_i}; the echo term needs e^{-j w Delta_i}.
      direct_[mic] = std::polar(1.0, first_omega * arrival_s_[mic]);
      direct_step_[mic] = std::polar(1.0, bin_omega_ * arrival_s_[mic]);
      echo_[mic] = std::polar(gain * level_[mic], -first_omega * delay_s_[mic]);
      echo_step_[mic] = std::polar(1.0, -bin_omega_ * delay_s_[mic]);
    }
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      const double weight = keep[index] != 0 ? weights[index] : 0.0;
      if (weight > 0.0) {
        std::complex<double> sum(0.0, 0.0);
        for (std::size_t mic = 0; mic < mics; ++mic) {
          const int m = static_cast<int>(mic);
          std::complex<double> aligned =
              std::complex<double>(gcc.unit_real(m)[index], gcc.unit_imag(m)[index]) * direct_[mic];
          if (gain > 0.0) {
            const std::complex<double> comb = 1.0 + echo_[mic];
            const double size = std::abs(comb);
            if (size > 1e-9) aligned *= std::conj(comb) / size;
          }
          sum += aligned;
        }
        total += weight * std::norm(sum);
        weight_sum += weight;
      }
      for (std::size_t mic = 0; mic < mics; ++mic) {
        direct_[mic] *= direct_step_[mic];
        echo_[mic] *= echo_step_[mic];
      }
    }
  }
  const double scale = weight_sum * static_cast<double>(mics * mics);
  return scale > 0.0 ? total / scale : 0.0;
}

void GroundEcho::search(const GccPhat& gcc, const Eigen::Vector3d& direction_site, bool full) {
  frames_since_search_ = 0;
  const double max_curvature = 1.0 / settings_.min_range_m;
  double curvature = curvature_per_m_;
  double gain = locked_ ? gain_ : kAcquisitionGain;
  if (full) {
    double best = -1.0;
    for (double candidate = 0.0; candidate <= max_curvature + 1e-12; candidate += kScanStep_per_m) {
      paths(direction_site, candidate);
      const double value = coherence(gcc, gain);
      if (value > best) {
        best = value;
        curvature = candidate;
      }
    }
  }
  // Local: a parabola in curvature at the current gain, then one in gain there.
  const double step = kLocalCurvatureStep_per_m;
  auto at_curvature = [&](double value) {
    paths(direction_site, std::clamp(value, 0.0, max_curvature));
    return coherence(gcc, gain);
  };
  const double left = at_curvature(curvature - step);
  const double right = at_curvature(curvature + step);
  const double centre = at_curvature(curvature);
  curvature =
      std::clamp(curvature + step * parabola_vertex(left, centre, right, 2.0), 0.0, max_curvature);
  paths(direction_site, curvature);
  const double lower = coherence(gcc, std::max(kMinGain, gain - kLocalGainStep));
  const double upper = coherence(gcc, std::min(kMaxGain, gain + kLocalGainStep));
  const double middle = coherence(gcc, gain);
  gain = std::clamp(gain + kLocalGainStep * parabola_vertex(lower, middle, upper, 1.5), kMinGain,
                    kMaxGain);
  const double with_echo = coherence(gcc, gain);
  const double without = coherence(gcc, 0.0);
  locked_ = with_echo > without * (1.0 + settings_.min_improvement);
  curvature_per_m_ = curvature;
  gain_ = gain;
}

bool GroundEcho::observe(const GccPhat& gcc, const Eigen::Vector3d& direction_site) {
  if (!(direction_site.z() >= min_sine_elevation_)) {
    // Near the horizon the reflection arrives with the direct path: nothing to separate.
    locked_ = false;
    return false;
  }
  if (direction_site.dot(last_direction_) < max_jump_cosine_) {
    // Another source (or the same after a gap): its range and ground are not known.
    locked_ = false;
    frames_since_search_ = settings_.acquire_every_frames;
  }
  last_direction_ = direction_site;
  ++frames_since_search_;
  if (locked_ && frames_since_search_ >= settings_.search_every_frames)
    search(gcc, direction_site, false);
  else if (!locked_ && frames_since_search_ >= settings_.acquire_every_frames)
    search(gcc, direction_site, true);
  return locked_;
}

void GroundEcho::remove(GccPhat& gcc, const Eigen::Vector3d& direction_site) {
  if (!locked_) return;
  paths(direction_site, curvature_per_m_);
  for (std::size_t mic = 0; mic < mics_m_.size(); ++mic) {
    std::size_t index = 0;
    for (const BandRun& run : runs_) {
      std::complex<double> echo =
          std::polar(gain_ * level_[mic], -run.first_bin * bin_omega_ * delay_s_[mic]);
      const std::complex<double> echo_step = std::polar(1.0, -bin_omega_ * delay_s_[mic]);
      for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
        const std::complex<double> comb = 1.0 + echo;
        const double size = std::abs(comb);
        rotation_[index] = size > 1e-9 ? std::conj(comb) / size : std::complex<double>(1.0, 0.0);
        echo *= echo_step;
      }
    }
    gcc.rotate_units(static_cast<int>(mic), rotation_);
  }
}

}  // namespace dronetrack::doa
