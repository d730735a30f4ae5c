#include "doa/ground_echo.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstring>
#include <limits>
#include <numbers>

#include "doa/simd/kernels.hpp"

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
// The search's rows are whole vectors of the wide kernels' eight lanes (a multiple of the
// two-lane ones').
constexpr int kVector = 8;
static_assert(kSearchBins % kVector == 0);

// Vertex of the parabola through (-step, left), (0, centre), (+step, right), as a multiple of
// step, clamped to [-limit, limit]; when the three make no maximum, limit towards the larger side
// (0 when flat).
double parabola_vertex(double left, double centre, double right, double limit) {
  const double curvature = left - 2.0 * centre + right;
  if (!(curvature < 0.0)) return left > right ? -limit : (right > left ? limit : 0.0);
  return std::clamp(0.5 * (left - right) / curvature, -limit, limit);
}

void phasors(const simd::PhasorRows& rows) { simd::phasor_rows(rows); }

// Search bins rounded up to whole vectors.
int vector_bins(int bins) { return (bins + kVector - 1) / kVector * kVector; }

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
  aligned_re_.assign(static_cast<std::size_t>(kSearchBins) * mics, 0.0);
  aligned_im_.assign(aligned_re_.size(), 0.0);
  echo_re_.assign(aligned_re_.size(), 0.0);
  echo_im_.assign(aligned_re_.size(), 0.0);
  corrected_re_.assign(band_omega_.size() * mics, 0.0);
  corrected_im_.assign(corrected_re_.size(), 0.0);
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

void GroundEcho::prepare(const GccPhat& gcc, std::span<const std::uint8_t> keep,
                         const Eigen::Vector3d& direction_site) {
  const std::span<const double> weights = gcc.bin_weight();
  double strongest = 0.0;
  for (std::size_t k = 0; k < keep.size(); ++k)
    strongest = std::max(strongest, keep[k] != 0 ? weights[k] : 0.0);
  // The source's own bins: the SNR weights' upper half (every kept bin with plain PHAT). Bins
  // with noise only would add chance coherence, not evidence. Without a branch per bin: which
  // bins pass is as good as random to a branch predictor.
  int count = 0;
  for (std::size_t k = 0; k < keep.size(); ++k) {
    candidates_[static_cast<std::size_t>(count)] = static_cast<int>(k);
    count += keep[k] != 0 && weights[k] > 0.0 && weights[k] >= 0.5 * strongest ? 1 : 0;
  }
  const int stride = std::max(1, (count + kSearchBins - 1) / kSearchBins);
  const std::size_t mics = mics_m_.size();
  for (std::size_t mic = 0; mic < mics; ++mic)
    arrival_s_[mic] = -direction_site.dot(mics_m_[mic]) / speed_of_sound_mps_;
  search_bins_ = 0;
  search_weight_sum_ = 0.0;
  std::fill(search_omega_.begin(), search_omega_.end(), 0.0);
  std::fill(search_weight_.begin(), search_weight_.end(), 0.0);
  std::fill(aligned_re_.begin(), aligned_re_.end(), 0.0);
  std::fill(aligned_im_.begin(), aligned_im_.end(), 0.0);
  for (int c = 0; c < count; c += stride) {
    const auto index = static_cast<std::size_t>(candidates_[static_cast<std::size_t>(c)]);
    const auto slot = static_cast<std::size_t>(search_bins_++);
    search_omega_[slot] = band_omega_[index];
    search_weight_[slot] = weights[index];
    search_weight_sum_ += weights[index];
    for (std::size_t mic = 0; mic < mics; ++mic) {
      aligned_re_[mic * kSearchBins + slot] = gcc.unit_real(static_cast<int>(mic))[index];
      aligned_im_[mic * kSearchBins + slot] = gcc.unit_imag(static_cast<int>(mic))[index];
    }
  }
  // e^{+j w t_i} undoes the direct path's delay: aligned units add up in phase.
  for (std::size_t mic = 0; mic < mics; ++mic) {
    const std::size_t row = mic * kSearchBins;
    phasors({search_omega_.data(),
             vector_bins(search_bins_),
             arrival_s_[mic],
             1.0,
             {aligned_re_.data() + row, aligned_im_.data() + row},
             {aligned_re_.data() + row, aligned_im_.data() + row}});
  }
}

void GroundEcho::candidate(const Eigen::Vector3d& direction_site, double curvature_per_m) {
  paths(direction_site, curvature_per_m);
  for (std::size_t mic = 0; mic < mics_m_.size(); ++mic) {
    const std::size_t row = mic * kSearchBins;
    phasors({search_omega_.data(),
             vector_bins(search_bins_),
             -delay_s_[mic],
             level_[mic],
             {nullptr, nullptr},
             {echo_re_.data() + row, echo_im_.data() + row}});
  }
}

double GroundEcho::coherence(double gain) const {
  const std::size_t mics = mics_m_.size();
  const double total = simd::echo_coherence({{aligned_re_.data(), aligned_im_.data()},
                                             {echo_re_.data(), echo_im_.data()},
                                             search_weight_.data(),
                                             mics,
                                             static_cast<std::size_t>(kSearchBins),
                                             vector_bins(search_bins_)},
                                            gain);
  const double scale = search_weight_sum_ * static_cast<double>(mics * mics);
  return scale > 0.0 ? total / scale : 0.0;
}

void GroundEcho::search(const GccPhat& gcc, std::span<const std::uint8_t> keep,
                        const Eigen::Vector3d& direction_site, bool full) {
  frames_since_search_ = 0;
  prepare(gcc, keep, direction_site);
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
      this->candidate(direction_site, candidate);
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
    candidate(direction_site, std::clamp(value, 0.0, max_curvature));
    return coherence(gain);
  };
  const double left = at_curvature(curvature - step);
  const double right = at_curvature(curvature + step);
  const double centre = at_curvature(curvature);
  curvature =
      std::clamp(curvature + step * parabola_vertex(left, centre, right, 2.0), 0.0, max_curvature);
  candidate(direction_site, curvature);
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
  return observe(gcc, direction_site, gcc.bin_keep());
}

bool GroundEcho::observe(const GccPhat& gcc, const Eigen::Vector3d& direction_site,
                         std::span<const std::uint8_t> keep) {
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
  if (search_now != Search::none) search(gcc, keep, direction_site, search_now == Search::full);
  return locked_;
}

GccPhat::UnitsView GroundEcho::corrected(const GccPhat::UnitsView& units,
                                         const Eigen::Vector3d& direction_site) {
  if (!locked_) return units;
  paths(direction_site, curvature_per_m_);
  const auto bins = static_cast<std::size_t>(units.bins);
  for (std::size_t mic = 0; mic < mics_m_.size(); ++mic) {
    const int m = static_cast<int>(mic);
    // conj(c) / |c| with c = 1 + g e^{-j w Delta}; |c| >= 1 - kMaxGain.
    simd::comb_divide({runs_.data(),
                       runs_.size(),
                       {units.real_row(m).data(), units.imag_row(m).data()},
                       {corrected_re_.data() + mic * bins, corrected_im_.data() + mic * bins},
                       gain_ * level_[mic],
                       -bin_omega_ * delay_s_[mic]});
  }
  return {corrected_re_.data(), corrected_im_.data(), units.bins};
}

}  // namespace dronetrack::doa
