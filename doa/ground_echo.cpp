#include "doa/ground_echo.hpp"

#include <algorithm>
#include <array>
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
// The search judges coherence on at most this many bins: the comb's period (1/Delta, 140 Hz and
// up) spans many 5.9 Hz bins, so a spread subset sees it as well as the whole band does.
constexpr int kSearchBins = 64;
constexpr int kMinSearchBins = 24;

// e^{j phase} from a table (linear interpolation, error < 3e-7): the search's inner loop.
constexpr int kPhaseTableSize = 4096;
const std::vector<std::complex<double>>& phase_table() {
  static const std::vector<std::complex<double>> table = [] {
    std::vector<std::complex<double>> values(kPhaseTableSize + 1);
    for (int i = 0; i <= kPhaseTableSize; ++i)
      values[static_cast<std::size_t>(i)] =
          std::polar(1.0, 2.0 * std::numbers::pi * i / kPhaseTableSize);
    return values;
  }();
  return table;
}

std::complex<double> unit_phasor(double phase_rad) {
  const double position = phase_rad * (kPhaseTableSize / (2.0 * std::numbers::pi));
  const double floor = std::floor(position);
  const double fraction = position - floor;
  const auto index =
      static_cast<std::size_t>(static_cast<std::int64_t>(floor) & (kPhaseTableSize - 1));
  const std::vector<std::complex<double>>& table = phase_table();
  return table[index] + fraction * (table[index + 1] - table[index]);
}

// Vertex of the parabola through (-step, left), (0, centre), (+step, right), as a multiple of
// step, clamped to [-limit, limit]; when the three make no maximum, limit towards the larger side
// (0 when flat).
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
  for (const BandRun& run : runs_)
    for (int k = run.first_bin; k <= run.last_bin; ++k) band_omega_.push_back(k * bin_omega_);
  candidates_.assign(band_omega_.size(), 0);
  search_omega_.assign(kSearchBins, 0.0);
  search_weight_.assign(kSearchBins, 0.0);
  aligned_.assign(static_cast<std::size_t>(kSearchBins) * mics, {});
  (void)phase_table();  // made here, not in the first frame's search
  cosines_.assign(static_cast<std::size_t>(gcc.band_bin_count()), 1.0);
  sines_.assign(static_cast<std::size_t>(gcc.band_bin_count()), 0.0);
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

void GroundEcho::prepare(const GccPhat& gcc, const Eigen::Vector3d& direction_site) {
  const std::span<const double> weights = gcc.bin_weight();
  const std::span<const std::uint8_t> keep = gcc.bin_keep();
  double strongest = 0.0;
  for (std::size_t k = 0; k < keep.size(); ++k)
    if (keep[k] != 0) strongest = std::max(strongest, weights[k]);
  // The source's own bins: the SNR weights' upper half (every kept bin with plain PHAT). Bins
  // with noise only would add chance coherence, not evidence.
  int count = 0;
  for (std::size_t k = 0; k < keep.size(); ++k)
    if (keep[k] != 0 && weights[k] > 0.0 && weights[k] >= 0.5 * strongest)
      candidates_[static_cast<std::size_t>(count++)] = static_cast<int>(k);
  const int stride = std::max(1, (count + kSearchBins - 1) / kSearchBins);
  const std::size_t mics = mics_m_.size();
  for (std::size_t mic = 0; mic < mics; ++mic)
    arrival_s_[mic] = -direction_site.dot(mics_m_[mic]) / speed_of_sound_mps_;
  search_bins_ = 0;
  for (int c = 0; c < count; c += stride) {
    const int index = candidates_[static_cast<std::size_t>(c)];
    const auto slot = static_cast<std::size_t>(search_bins_++);
    search_omega_[slot] = band_omega_[static_cast<std::size_t>(index)];
    search_weight_[slot] = weights[static_cast<std::size_t>(index)];
    for (std::size_t mic = 0; mic < mics; ++mic) {
      const int m = static_cast<int>(mic);
      // e^{+j w t_i} undoes the direct path's delay: aligned units add up in phase.
      aligned_[slot * mics + mic] =
          std::complex<double>(gcc.unit_real(m)[static_cast<std::size_t>(index)],
                               gcc.unit_imag(m)[static_cast<std::size_t>(index)]) *
          unit_phasor(search_omega_[slot] * arrival_s_[mic]);
    }
  }
}

double GroundEcho::coherence(double gain) const {
  const std::size_t mics = mics_m_.size();
  double total = 0.0;
  double weight_sum = 0.0;
  for (std::size_t bin = 0; bin < static_cast<std::size_t>(search_bins_); ++bin) {
    const std::complex<double>* aligned = aligned_.data() + bin * mics;
    std::complex<double> sum(0.0, 0.0);
    for (std::size_t mic = 0; mic < mics; ++mic) {
      if (gain <= 0.0) {
        sum += aligned[mic];
        continue;
      }
      const std::complex<double> comb =
          1.0 + gain * level_[mic] * unit_phasor(-search_omega_[bin] * delay_s_[mic]);
      const double size = std::sqrt(std::norm(comb));  // not std::abs: hypot is slow
      sum += size > 1e-9 ? aligned[mic] * std::conj(comb) / size : aligned[mic];
    }
    total += search_weight_[bin] * std::norm(sum);
    weight_sum += search_weight_[bin];
  }
  const double scale = weight_sum * static_cast<double>(mics * mics);
  return scale > 0.0 ? total / scale : 0.0;
}

void GroundEcho::search(const GccPhat& gcc, const Eigen::Vector3d& direction_site, bool full) {
  frames_since_search_ = 0;
  prepare(gcc, direction_site);
  if (search_bins_ < kMinSearchBins) {
    // Two parameters fitted to a handful of bins fit their noise: a source heard in few bins
    // (next to a nulled generator, at 0 dB) would lock onto a made-up echo.
    locked_ = false;
    return;
  }
  const double max_curvature = 1.0 / settings_.min_range_m;
  double curvature = curvature_per_m_;
  double gain = locked_ ? gain_ : kAcquisitionGain;
  if (full) {
    double best = -1.0;
    for (double candidate = 0.0; candidate <= max_curvature + 1e-12; candidate += kScanStep_per_m) {
      paths(direction_site, candidate);
      const double value = coherence(gain);
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
    return coherence(gain);
  };
  const double left = at_curvature(curvature - step);
  const double right = at_curvature(curvature + step);
  const double centre = at_curvature(curvature);
  curvature =
      std::clamp(curvature + step * parabola_vertex(left, centre, right, 2.0), 0.0, max_curvature);
  paths(direction_site, curvature);
  const double lower = coherence(std::max(kMinGain, gain - kLocalGainStep));
  const double upper = coherence(std::min(kMaxGain, gain + kLocalGainStep));
  const double middle = coherence(gain);
  gain = std::clamp(gain + kLocalGainStep * parabola_vertex(lower, middle, upper, 1.5), kMinGain,
                    kMaxGain);
  const double with_echo = coherence(gain);
  const double without = coherence(0.0);
  locked_ = with_echo > without * (1.0 + settings_.min_improvement);
  curvature_per_m_ = curvature;
  gain_ = gain;
}

GroundEcho::Search GroundEcho::next_search(const Eigen::Vector3d& direction_site) const {
  if (!(direction_site.z() >= min_sine_elevation_)) return Search::none;
  // A jump is another source (or the same after a gap): its range and ground are not known.
  const bool jump = direction_site.dot(last_direction_) < max_jump_cosine_;
  const int frames = (jump ? settings_.acquire_every_frames : frames_since_search_) + 1;
  if (locked_ && !jump)
    return frames >= settings_.search_every_frames ? Search::local : Search::none;
  return frames >= settings_.acquire_every_frames ? Search::full : Search::none;
}

bool GroundEcho::search_due(const Eigen::Vector3d& direction_site) const {
  return next_search(direction_site) != Search::none;
}

bool GroundEcho::observe(const GccPhat& gcc, const Eigen::Vector3d& direction_site) {
  if (!(direction_site.z() >= min_sine_elevation_)) {
    // Near the horizon the reflection arrives with the direct path: nothing to separate.
    locked_ = false;
    return false;
  }
  const Search search_now = next_search(direction_site);
  if (direction_site.dot(last_direction_) < max_jump_cosine_) {
    locked_ = false;
    frames_since_search_ = settings_.acquire_every_frames;
  }
  last_direction_ = direction_site;
  ++frames_since_search_;
  if (search_now != Search::none) search(gcc, direction_site, search_now == Search::full);
  return locked_;
}

void GroundEcho::remove(GccPhat& gcc, const Eigen::Vector3d& direction_site) {
  if (!locked_) return;
  paths(direction_site, curvature_per_m_);
  gcc.save_units();
  constexpr int kLanes = 8;
  for (std::size_t mic = 0; mic < mics_m_.size(); ++mic) {
    const double level = gain_ * level_[mic];
    const double phase_step = -bin_omega_ * delay_s_[mic];
    // e^{-j w_k Delta} along each run by eight interleaved recurrences: each lane waits only for
    // its own previous product, so the loop runs in vector lanes, and the error after the band's
    // few dozen steps per lane is ~1e-14.
    const double step_re = std::cos(kLanes * phase_step);
    const double step_im = std::sin(kLanes * phase_step);
    std::size_t index = 0;
    for (const BandRun& run : runs_) {
      std::array<double, kLanes> echo_re{};
      std::array<double, kLanes> echo_im{};
      for (int lane = 0; lane < kLanes; ++lane) {
        echo_re[lane] = std::cos((run.first_bin + lane) * phase_step);
        echo_im[lane] = std::sin((run.first_bin + lane) * phase_step);
      }
      const int count = run.last_bin - run.first_bin + 1;
      for (int block = 0; block < count; block += kLanes) {
        const int lanes = std::min(kLanes, count - block);
        for (int lane = 0; lane < lanes; ++lane) {
          // conj(c) / |c| with c = 1 + g e^{-j w Delta}.
          const double comb_re = 1.0 + level * echo_re[lane];
          const double comb_im = level * echo_im[lane];
          const double norm = comb_re * comb_re + comb_im * comb_im;
          const double inverse = norm > 1e-18 ? 1.0 / std::sqrt(norm) : 0.0;
          cosines_[index + static_cast<std::size_t>(block + lane)] =
              norm > 1e-18 ? comb_re * inverse : 1.0;
          sines_[index + static_cast<std::size_t>(block + lane)] = -comb_im * inverse;
        }
        for (int lane = 0; lane < kLanes; ++lane) {
          const double re = echo_re[lane];
          echo_re[lane] = re * step_re - echo_im[lane] * step_im;
          echo_im[lane] = re * step_im + echo_im[lane] * step_re;
        }
      }
      index += static_cast<std::size_t>(count);
    }
    gcc.rotate_units(static_cast<int>(mic), cosines_, sines_);
  }
}

void GroundEcho::restore(GccPhat& gcc) const {
  if (locked_) gcc.restore_units();
}

}  // namespace dronetrack::doa
