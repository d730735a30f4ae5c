#include "doa/acoustic_features.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>

#include "doa/comb_line_cleaning.hpp"
#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

namespace {

// Rings of directions the lines' power is compared on: 2 deg apart (a quarter of this array's
// ~8 deg beam at 3 kHz, so a peak between rings loses little), out to 20 deg (two beams: a
// source farther than that from the one checked rarely puts its lines into its bins above
// min_bin_coherence).
constexpr double kLineRingStepDeg = 2.0;
constexpr double kLineSearchRadiusDeg = 20.0;

BandRun feature_bins(const FrequencyBand& band_hz, double sample_rate_hz, int fft_size) {
  const std::vector<BandRun> runs = band_runs({band_hz}, sample_rate_hz, fft_size);
  return {runs.front().first_bin, runs.back().last_bin};
}

}  // namespace

AcousticFeatureExtractor::AcousticFeatureExtractor(const ArrayGeometry& geometry, int fft_size,
                                                   double sample_rate_hz, double speed_of_sound_mps,
                                                   double hop_s, const AcousticSettings& settings)
    : settings_(settings),
      mic_count_(static_cast<int>(geometry.mic_count())),
      band_(feature_bins(settings.band_hz, sample_rate_hz, fft_size)),
      first_bin_(band_.first_bin),
      bin_count_(band_.last_bin - band_.first_bin + 1),
      bin_omega_(2.0 * std::numbers::pi * sample_rate_hz / fft_size),
      speed_of_sound_mps_(speed_of_sound_mps),
      detector_(first_bin_, bin_count_, sample_rate_hz / fft_size, settings.comb) {
  if (settings.analysis_every_frames < 1)
    throw std::invalid_argument("acoustic features: analysis_every_frames must be >= 1");
  if (!(settings.comb_memory_s > 0.0) || !(settings.history_s > 0.0))
    throw std::invalid_argument("acoustic features: comb_memory_s and history_s must be > 0");
  if (mic_count_ < 2 || mic_count_ > kMaxMics)
    throw std::invalid_argument("acoustic features: 2 to 8 mics");
  interval_s_ = hop_s * settings.analysis_every_frames;
  comb_weight_ = std::min(1.0, interval_s_ / settings.comb_memory_s);
  const int entries =
      std::clamp(static_cast<int>(std::lround(settings.history_s / interval_s_)), 2, 256);
  const Eigen::Vector3d centre = geometry.centre_site_m();
  for (std::size_t m = 0; m < geometry.mic_count(); ++m)
    mic_offsets_site_m_.push_back(geometry.mic_site_m(m) - centre);
  source_power_.resize(static_cast<std::size_t>(kMaxSources * bin_count_));
  mic_power_.resize(static_cast<std::size_t>(bin_count_));
  sorted_power_.reserve(static_cast<std::size_t>(bin_count_));
  frame_autocorrelation_.resize(static_cast<std::size_t>(detector_.lag_count()));
  mean_before_.resize(static_cast<std::size_t>(detector_.lag_count()));
  on_line_.resize(static_cast<std::size_t>(bin_count_));
  line_bins_.reserve(static_cast<std::size_t>(bin_count_));
  line_excess_.resize(static_cast<std::size_t>(bin_count_ * mic_count_ * mic_count_));
  line_tolerance_rad_ = settings.line_direction_tolerance_deg * std::numbers::pi / 180.0;
  for (History& history : histories_) {
    history.mean_autocorrelation.assign(static_cast<std::size_t>(detector_.lag_count()), 0.0);
    history.entries.resize(static_cast<std::size_t>(entries));
  }
}

const AcousticFeatures& AcousticFeatureExtractor::features(int slot) const {
  if (slot < 0 || slot >= kMaxSlots) return none_;
  return histories_[static_cast<std::size_t>(slot)].features;
}

// Delay-and-sum per bin toward every source; the bin's power goes to the source that makes it
// most coherent, if coherent enough. A plane wave from direction u reaches mic m (offset d_m
// from the centroid) d_m.u / c early, so its phasor there is S e^{+j w d_m.u / c}.
void AcousticFeatureExtractor::assign_bins(const MultichannelFft& fft, int sources) {
  // Per bin the mics' mean power and the most coherent source's steered power (doa/simd); the
  // delays are one block of kMaxSources rows of kMaxMics.
  static_assert(kMaxSources <= simd::kMaxSteeredSources && kMaxMics <= simd::kMaxSteeredMics);
  static_assert(sizeof(delays_s_) == sizeof(double) * kMaxSources * kMaxMics);
  std::array<const std::complex<double>*, kMaxMics> spectra{};
  for (int m = 0; m < mic_count_; ++m) spectra[static_cast<std::size_t>(m)] = fft.spectrum(m);
  simd::steered_bins({spectra.data(), mic_count_, first_bin_, bin_count_, bin_omega_,
                      delays_s_.front().data(), kMaxMics, sources, settings_.min_bin_coherence,
                      mic_power_.data(), source_power_.data()});
  // A bin another source (or nobody) owns is this source's background: the frame's typical
  // bin power, or the bin's own if lower. Not zero: a sparse source's lines need a floor to
  // stand on; not the bin's own power: a broadband source would then see the other source's
  // lines as its own comb.
  sorted_power_.assign(mic_power_.begin(), mic_power_.end());
  const auto middle = sorted_power_.begin() + static_cast<std::ptrdiff_t>(sorted_power_.size() / 2);
  std::nth_element(sorted_power_.begin(), middle, sorted_power_.end());
  const double typical = *middle;
  typical_power_ = typical;
  for (int s = 0; s < sources; ++s) {
    double owned = 0.0;
    for (int i = 0; i < bin_count_; ++i) {
      double& power = source_power_[static_cast<std::size_t>(s * bin_count_ + i)];
      owned += power;
      if (power == 0.0) power = std::min(mic_power_[static_cast<std::size_t>(i)], typical);
    }
    owned_power_[static_cast<std::size_t>(s)] = owned;
  }
}

void AcousticFeatureExtractor::analyse(const MultichannelFft& fft,
                                       std::span<const Eigen::Vector3d> directions_site,
                                       std::span<const int> slots,
                                       std::span<const std::uint32_t> generations) {
  const int sources =
      std::min<int>({static_cast<int>(directions_site.size()), static_cast<int>(slots.size()),
                     static_cast<int>(generations.size()), kMaxSources});
  if (sources == 0 || fft.channels() != mic_count_) return;
  lines_fundamental_hz_ = 0.0;  // a new frame: no comb's lines made yet
  for (int s = 0; s < sources; ++s)
    source_directions_[static_cast<std::size_t>(s)] = directions_site[static_cast<std::size_t>(s)];
  for (int s = 0; s < sources; ++s)
    for (int m = 0; m < mic_count_; ++m)
      delays_s_[s][m] = -mic_offsets_site_m_[static_cast<std::size_t>(m)].dot(
                            directions_site[static_cast<std::size_t>(s)]) /
                        speed_of_sound_mps_;
  assign_bins(fft, sources);
  // Power per windowed sample, one-sided (as the node's in-band level).
  const double to_power = 2.0 / (static_cast<double>(fft.fft_size()) * fft.window_energy());
  for (int s = 0; s < sources; ++s) {
    const int slot = slots[static_cast<std::size_t>(s)];
    if (slot < 0 || slot >= kMaxSlots) continue;
    History& history = histories_[static_cast<std::size_t>(slot)];
    const std::uint32_t generation = generations[static_cast<std::size_t>(s)];
    if (!history.started || history.generation != generation) {
      history.started = false;
      history.generation = generation;
      history.size = 0;
      history.next = 0;
    }
    const std::span<double> power(source_power_.data() + s * bin_count_,
                                  static_cast<std::size_t>(bin_count_));
    const double band_power = owned_power_[static_cast<std::size_t>(s)];
    detector_.autocorrelate(power, frame_autocorrelation_);
    const double weight = history.started ? comb_weight_ : 1.0;
    history.started = true;
    std::copy(history.mean_autocorrelation.begin(), history.mean_autocorrelation.end(),
              mean_before_.begin());
    const auto remember = [&] {
      for (std::size_t l = 0; l < frame_autocorrelation_.size(); ++l)
        history.mean_autocorrelation[l] =
            mean_before_[l] + weight * (frame_autocorrelation_[l] - mean_before_[l]);
    };
    remember();
    HarmonicComb comb = detector_.find(history.mean_autocorrelation);
    // Lines another source put in this one's bins are not its evidence: the comb this frame
    // shows and the comb the memory reports, each judged on this frame's lines; lines that
    // point elsewhere leave the spectrum, and a reported comb whose lines do is not reported.
    if (line_tolerance_rad_ > 0.0) {
      const HarmonicComb frame_comb = detector_.find(frame_autocorrelation_);
      if (frame_comb.found && !lines_point_at(fft, frame_comb, s)) {
        drop_lines(power);
        detector_.autocorrelate(power, frame_autocorrelation_);
        remember();
        comb = detector_.find(history.mean_autocorrelation);
      }
      if (comb.found && !lines_point_at(fft, comb, s)) {
        drop_lines(power);
        detector_.autocorrelate(power, frame_autocorrelation_);
        remember();
        comb = HarmonicComb{};
      }
    }
    update_history(history, comb, 10.0 * std::log10(std::max(band_power * to_power, 1e-30)));
  }
}

double AcousticFeatureExtractor::line_power(const Eigen::Vector3d& direction) const {
  // The plane wave from `direction` is turned back by its lead at each mic (assign_bins).
  std::array<double, kMaxMics> lead_s{};
  for (int m = 0; m < mic_count_; ++m)
    lead_s[static_cast<std::size_t>(m)] =
        mic_offsets_site_m_[static_cast<std::size_t>(m)].dot(direction) / speed_of_sound_mps_;
  const auto mics = static_cast<std::size_t>(mic_count_);
  std::array<std::complex<double>, kMaxMics> turn{};
  double total = 0.0;
  for (std::size_t l = 0; l < line_bins_.size(); ++l) {
    const double omega = bin_omega_ * (first_bin_ + line_bins_[l]);
    for (std::size_t m = 0; m < mics; ++m) turn[m] = std::polar(1.0, -omega * lead_s[m]);
    const std::complex<double>* excess = line_excess_.data() + l * mics * mics;
    double power = 0.0;
    for (std::size_t m = 0; m < mics; ++m) {
      power += excess[m * mics + m].real();
      for (std::size_t n = m + 1; n < mics; ++n)
        power += 2.0 * (turn[m] * std::conj(turn[n]) * excess[m * mics + n]).real();
    }
    total += power;
  }
  return total;
}

// Each line bin's cross-spectral matrix X X^H minus the mean of its off-line neighbours'
// (comb_line_cleaning.hpp's neighbourhood): a broadband source in the same beam (the one checked,
// a car's tyres) is smooth across bins and leaves it; what is left is the line's own wave.
void AcousticFeatureExtractor::line_excess(const MultichannelFft& fft) {
  const auto mics = static_cast<std::size_t>(mic_count_);
  for (std::size_t l = 0; l < line_bins_.size(); ++l) {
    std::complex<double>* excess = line_excess_.data() + l * mics * mics;
    const int line = line_bins_[l];
    std::fill(excess, excess + mics * mics, std::complex<double>{});
    int neighbours = 0;
    for (int offset = kLineNeighbourFirst; offset <= kLineNeighbourBins; ++offset)
      for (const int i : {line - offset, line + offset}) {
        if (i < 0 || i >= bin_count_ || on_line_[static_cast<std::size_t>(i)] != 0) continue;
        for (std::size_t m = 0; m < mics; ++m)
          for (std::size_t n = m; n < mics; ++n)
            excess[m * mics + n] += fft.spectrum(static_cast<int>(m))[first_bin_ + i] *
                                    std::conj(fft.spectrum(static_cast<int>(n))[first_bin_ + i]);
        ++neighbours;
      }
    const double scale = neighbours > 0 ? -1.0 / neighbours : 0.0;
    for (std::size_t m = 0; m < mics; ++m)
      for (std::size_t n = m; n < mics; ++n)
        excess[m * mics + n] = scale * excess[m * mics + n] +
                               fft.spectrum(static_cast<int>(m))[first_bin_ + line] *
                                   std::conj(fft.spectrum(static_cast<int>(n))[first_bin_ + line]);
  }
}

// The harmonics' steered power on rings around the source's direction (kLineRingStepDeg apart,
// out to kLineSearchRadiusDeg): the comb is the source's when the highest power within the
// tolerance is at least the highest beyond it. A comb of this source peaks at its direction
// (within its DOA's error); another source's comb (one the frame did not find) whose lines fell
// into this source's beam peaks at that source's direction. Two choices the draw-33 trace
// forced (docs/classification.md, "Whose lines"): every harmonic of the spacing is judged, not
// only the lines that stand out in this source's bins (those were chosen for their coherence
// along its steering, and their power peaked there as much as at their own source), and each is
// judged on its excess over its neighbours' cross-spectra (this source's broadband, smooth
// across bins, is in every line bin too and would pull the peak to it).
bool AcousticFeatureExtractor::lines_point_at(const MultichannelFft& fft, const HarmonicComb& comb,
                                              int source) {
  // Every harmonic of the comb's spacing, not only the lines that stand out in this source's
  // bins, which are chosen by their coherence along its steering (make_lines). The lines and their
  // cross-spectra depend on the frame and the spacing only, not on the source: the frame's comb
  // and the remembered one (and other sources' combs) often share a spacing, made once for it.
  if (comb.fundamental_hz != lines_fundamental_hz_) {
    make_lines(fft, comb.fundamental_hz);
    lines_fundamental_hz_ = comb.fundamental_hz;
  }
  if (line_bins_.empty()) return true;
  const Eigen::Vector3d& centre = source_directions_[static_cast<std::size_t>(source)];
  const Eigen::Vector3d helper =
      std::abs(centre.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d east = centre.cross(helper).normalized();
  const Eigen::Vector3d north = east.cross(centre);
  constexpr double kDegree = std::numbers::pi / 180.0;
  double inside = line_power(centre);
  double outside = 0.0;
  const int rings = static_cast<int>(std::lround(kLineSearchRadiusDeg / kLineRingStepDeg));
  for (int ring = 1; ring <= rings; ++ring) {
    const double radius = ring * kLineRingStepDeg * kDegree;
    const int points = static_cast<int>(std::ceil(2.0 * std::numbers::pi * ring));
    for (int point = 0; point < points; ++point) {
      const double azimuth = 2.0 * std::numbers::pi * point / points;
      const Eigen::Vector3d direction =
          std::cos(radius) * centre +
          std::sin(radius) * (std::cos(azimuth) * east + std::sin(azimuth) * north);
      const double power = line_power(direction);
      if (radius <= line_tolerance_rad_ + 1e-9)
        inside = std::max(inside, power);
      else
        outside = std::max(outside, power);
    }
  }
  return outside <= inside;
}

// Every harmonic of `fundamental_hz` in the band, each at the loudest bin (mean over the mics)
// within 2 bins of it, +-1 bin, into line_bins_, and their cross-spectra's excess.
void AcousticFeatureExtractor::make_lines(const MultichannelFft& fft, double fundamental_hz) {
  std::fill(on_line_.begin(), on_line_.end(), std::uint8_t{0});
  const double bin_hz = bin_omega_ / (2.0 * std::numbers::pi);
  for (int harmonic = 1;; ++harmonic) {
    const int centre =
        static_cast<int>(std::lround(harmonic * fundamental_hz / bin_hz)) - first_bin_;
    if (centre - 2 >= bin_count_) break;
    if (centre + 2 < 0) continue;
    int peak = -1;
    for (int i = std::max(0, centre - 2); i <= std::min(bin_count_ - 1, centre + 2); ++i)
      if (peak < 0 ||
          mic_power_[static_cast<std::size_t>(i)] > mic_power_[static_cast<std::size_t>(peak)])
        peak = i;
    for (int i = std::max(0, peak - 1); i <= std::min(bin_count_ - 1, peak + 1); ++i)
      on_line_[static_cast<std::size_t>(i)] = 1;
  }
  line_bins_.clear();
  for (int i = 0; i < bin_count_; ++i)
    if (on_line_[static_cast<std::size_t>(i)] != 0) line_bins_.push_back(i);
  if (!line_bins_.empty()) line_excess(fft);
}

void AcousticFeatureExtractor::drop_lines(std::span<double> power) {
  for (const int i : line_bins_)
    power[static_cast<std::size_t>(i)] =
        std::min(mic_power_[static_cast<std::size_t>(i)], typical_power_);
}

void AcousticFeatureExtractor::update_history(History& history, const HarmonicComb& comb,
                                              double level_db) {
  const auto capacity = static_cast<int>(history.entries.size());
  history.entries[static_cast<std::size_t>(history.next)] = {comb.found, comb.fundamental_hz,
                                                             level_db};
  history.next = (history.next + 1) % capacity;
  history.size = std::min(history.size + 1, capacity);

  int combs = 0;
  double f0_sum = 0.0;
  double f0_sum2 = 0.0;
  double level_sum = 0.0;
  double level_sum2 = 0.0;
  for (int i = 0; i < history.size; ++i) {
    const History::Entry& entry = history.entries[static_cast<std::size_t>(i)];
    level_sum += entry.level_db;
    level_sum2 += entry.level_db * entry.level_db;
    if (!entry.comb) continue;
    ++combs;
    f0_sum += entry.fundamental_hz;
    f0_sum2 += entry.fundamental_hz * entry.fundamental_hz;
  }
  AcousticFeatures& features = history.features;
  features.valid = true;
  features.fundamental_hz = comb.fundamental_hz;
  features.comb_strength = comb.strength;
  features.harmonic_count = comb.harmonic_count;
  features.broadband_share = 1.0 - comb.harmonic_share;
  features.comb_persistence = static_cast<double>(combs) / history.size;
  features.fundamental_spread = 0.0;
  if (combs >= 3) {
    const double mean = f0_sum / combs;
    const double variance = std::max(0.0, f0_sum2 / combs - mean * mean);
    features.fundamental_spread = mean > 0.0 ? std::sqrt(variance) / mean : 0.0;
  }
  const double level_mean = level_sum / history.size;
  features.level_modulation_db =
      std::sqrt(std::max(0.0, level_sum2 / history.size - level_mean * level_mean));
  features.history_s = history.size * interval_s_;
}

}  // namespace dronetrack::doa
