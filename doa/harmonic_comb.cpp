#include "doa/harmonic_comb.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

#include "doa/simd/kernels.hpp"

namespace dronetrack::doa {

namespace {

// Vertex of the parabola through (-1, left), (0, centre), (1, right), in [-0.5, 0.5].
double parabolic_offset(double left, double centre, double right) {
  const double curvature = left - 2.0 * centre + right;
  if (!(curvature < 0.0)) return 0.0;
  return std::clamp(0.5 * (left - right) / curvature, -0.5, 0.5);
}

bool has_power(double power) { return power > 0.0 && std::isfinite(power); }

// 10 log10(x) for x > 0 from the float's exponent and a cubic in its mantissa (error < 0.01 dB:
// salience thresholds are whole dB). std::log10 per bin was a third of the detector's cost.
float fast_db(double x) {
  const float value = static_cast<float>(x);
  std::uint32_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  const auto exponent = static_cast<float>(static_cast<int>((bits >> 23) & 0xFFu) - 127);
  bits = (bits & 0x007FFFFFu) | 0x3F800000u;  // mantissa in [1, 2)
  float m;
  std::memcpy(&m, &bits, sizeof m);
  // log2(m) on [1, 2): minimax cubic.
  const float log2_m = -1.7417939f + (2.8212026f + (-1.4699568f + 0.44717955f * m) * m) * m;
  constexpr float kDbPerOctave = 3.0102999566f;  // 10 log10(2)
  return (exponent + log2_m) * kDbPerOctave;
}

}  // namespace

HarmonicCombDetector::HarmonicCombDetector(int first_bin, int bin_count, double bin_hz,
                                           const HarmonicCombSettings& settings)
    : settings_(settings), first_bin_(first_bin), bin_count_(bin_count), bin_hz_(bin_hz) {
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("harmonic comb: " + what);
  };
  if (first_bin < 0) fail("first_bin must be >= 0");
  if (!(bin_hz > 0.0) || !std::isfinite(bin_hz)) fail("bin_hz must be > 0");
  if (!(settings.min_fundamental_hz > 0.0) ||
      !(settings.max_fundamental_hz > settings.min_fundamental_hz))
    fail("need 0 < min_fundamental_hz < max_fundamental_hz");
  if (!(settings.envelope_half_width_hz > 0.0)) fail("envelope_half_width_hz must be > 0");
  if (settings.min_harmonics < 2) fail("min_harmonics must be >= 2");
  const int min_lag =
      std::max(2, static_cast<int>(std::floor(settings.min_fundamental_hz / bin_hz)));
  // At least two spacings inside the bins.
  const int max_lag =
      std::min(bin_count / 2, static_cast<int>(std::ceil(settings.max_fundamental_hz / bin_hz)));
  if (max_lag < min_lag + 2)
    fail("the bins (" + std::to_string(bin_count) + " of " + std::to_string(bin_hz) +
         " Hz) hold fewer than two spacings of the largest fundamental searched");
  first_lag_ = min_lag - 1;
  last_lag_ = max_lag + 1;
  envelope_half_width_bins_ =
      std::max(2, static_cast<int>(std::lround(settings.envelope_half_width_hz / bin_hz)));
  const auto size = static_cast<std::size_t>(bin_count);
  power_.resize(size);
  log_power_.resize(size);
  prefix_.resize(size + 1);
  prefix_count_.resize(size + 1);
  salience_.resize(size);
  autocorrelation_.resize(static_cast<std::size_t>(lag_count()));
}

int HarmonicCombDetector::measure_salience(std::span<const double> power) {
  const int n = bin_count_;
  valid_ = false;
  // Envelope: mean log power of the bins with power within +-W (prefix sums), so the salience
  // is each bin's standing above its neighbourhood in dB.
  prefix_[0] = 0.0;
  prefix_count_[0] = 0;
  total_power_ = 0.0;
  for (int i = 0; i < n; ++i) {
    const double p = i < static_cast<int>(power.size()) ? power[static_cast<std::size_t>(i)] : 0.0;
    const bool valid = has_power(p);
    power_[i] = valid ? p : 0.0;
    log_power_[i] = valid ? fast_db(p) : 0.0;
    prefix_[i + 1] = prefix_[i] + log_power_[i];
    prefix_count_[i + 1] = prefix_count_[i] + (valid ? 1 : 0);
    total_power_ += power_[i];
  }
  if (prefix_count_[n] < 2 * (first_lag_ + 1) || !(total_power_ > 0.0)) return 0;
  double salience_sum = 0.0;
  int salient = 0;
  for (int i = 0; i < n; ++i) {
    if (power_[i] == 0.0) {
      salience_[i] = 0.0;
      continue;
    }
    const int low = std::max(0, i - envelope_half_width_bins_);
    const int high = std::min(n, i + envelope_half_width_bins_ + 1);
    const int count = prefix_count_[high] - prefix_count_[low];
    const double envelope = (prefix_[high] - prefix_[low]) / std::max(count, 1);
    salience_[i] = static_cast<float>(std::max(0.0, log_power_[i] - envelope));
    salience_sum += salience_[i];
    // The margin covers the float rounding of the mean-free salience walk_lines() reads.
    salient += static_cast<double>(salience_[i]) >= settings_.line_salience_db - 1e-3 ? 1 : 0;
  }
  salience_mean_ = salience_sum / n;
  double energy = 0.0;
  for (int i = 0; i < n; ++i) {
    salience_[i] -= static_cast<float>(salience_mean_);
    energy += static_cast<double>(salience_[i]) * salience_[i];
  }
  valid_ = energy > 0.0;
  energy_ = energy;
  return salient;
}

void HarmonicCombDetector::autocorrelate_salience(std::span<double> autocorrelation) const {
  // Normalised; n / (n - L) undoes the shrinking overlap.
  const int n = bin_count_;
  for (int lag = first_lag_; lag <= last_lag_; ++lag) {
    autocorrelation[static_cast<std::size_t>(lag - first_lag_)] =
        simd::lagged_product(salience_.data(), n, lag) / energy_ * n / static_cast<double>(n - lag);
  }
}

void HarmonicCombDetector::autocorrelate(std::span<const double> power,
                                         std::span<double> autocorrelation) {
  std::fill(autocorrelation.begin(), autocorrelation.end(), 0.0);
  measure_salience(power);
  if (valid_) autocorrelate_salience(autocorrelation);
}

// The most salient bin near each multiple of the fundamental in the last spectrum, where it
// stands line_salience_db over its envelope: on_line(index) per line; returns how many.
template <typename OnLine>
int HarmonicCombDetector::walk_lines(double fundamental_hz, OnLine&& on_line) const {
  const int n = bin_count_;
  const double lag = fundamental_hz / bin_hz_;
  const int first_harmonic =
      std::max(1, static_cast<int>(std::ceil(first_bin_ * bin_hz_ / fundamental_hz)));
  const int last_harmonic =
      static_cast<int>(std::floor((first_bin_ + n - 1) * bin_hz_ / fundamental_hz));
  const int reach = std::max(1, static_cast<int>(0.25 * lag));
  int lines = 0;
  for (int h = first_harmonic; h <= last_harmonic; ++h) {
    const int expected = static_cast<int>(std::lround(h * fundamental_hz / bin_hz_)) - first_bin_;
    int peak = -1;
    double peak_salience = 0.0;
    for (int i = std::max(0, expected - reach); i <= std::min(n - 1, expected + reach); ++i) {
      if (salience_[i] + salience_mean_ > peak_salience) {
        peak_salience = salience_[i] + salience_mean_;
        peak = i;
      }
    }
    if (peak < 0 || peak_salience < settings_.line_salience_db) continue;
    ++lines;
    on_line(peak);
  }
  return lines;
}

int HarmonicCombDetector::mark_lines(const HarmonicComb& comb,
                                     std::span<std::uint8_t> on_line) const {
  std::fill(on_line.begin(), on_line.end(), std::uint8_t{0});
  if (!comb.found || !valid_) return 0;
  return walk_lines(comb.fundamental_hz, [&](int peak) {
    for (int i = std::max(peak - 1, 0); i <= std::min(bin_count_ - 1, peak + 1); ++i)
      if (static_cast<std::size_t>(i) < on_line.size()) on_line[static_cast<std::size_t>(i)] = 1;
  });
}

HarmonicComb HarmonicCombDetector::find(std::span<const double> autocorrelation) const {
  HarmonicComb comb;
  if (static_cast<int>(autocorrelation.size()) < lag_count()) return comb;
  const auto at = [&](int lag) {
    return autocorrelation[static_cast<std::size_t>(lag - first_lag_)];
  };
  const int min_lag = first_lag_ + 1;
  const int max_lag = last_lag_ - 1;
  int best_lag = min_lag;
  for (int lag = min_lag; lag <= max_lag; ++lag)
    if (at(lag) > at(best_lag)) best_lag = lag;
  const double best = at(best_lag);
  if (!(best > 0.0)) return comb;
  // The comb's own spacing, not a multiple of it. A comb at spacing L correlates at 2L and 3L
  // too, and when L is not a whole number of bins the integer lag nearest 2L can even beat it;
  // but at L/2 and L/3 a comb anti-correlates (its lines fall on its gaps). So from the best lag
  // go down to best/2 or best/3 while the autocorrelation there holds at least half of it.
  const auto local_max_near = [&](double centre) {
    const int middle = static_cast<int>(std::lround(centre));
    int found = -1;
    for (int candidate = std::max(min_lag, middle - 1); candidate <= std::min(max_lag, middle + 1);
         ++candidate)
      if (found < 0 || at(candidate) > at(found)) found = candidate;
    return found;
  };
  int lag = best_lag;
  for (bool moved = true; moved;) {
    moved = false;
    for (const int divisor : {2, 3}) {
      const double centre = static_cast<double>(lag) / divisor;
      if (centre < min_lag - 0.5) continue;
      const int candidate = local_max_near(centre);
      if (candidate >= min_lag && candidate < lag && at(candidate) >= 0.5 * at(lag)) {
        lag = candidate;
        moved = true;
        break;
      }
    }
  }
  comb.strength = std::clamp(at(lag), 0.0, 1.0);
  const double refined_lag = lag + parabolic_offset(at(lag - 1), at(lag), at(lag + 1));
  const double fundamental_hz = refined_lag * bin_hz_;

  // The lines of the last spectrum on this comb.
  if (valid_) {
    double harmonic_power = 0.0;
    int previous_end = -1;
    comb.harmonic_count = walk_lines(fundamental_hz, [&](int peak) {
      for (int i = std::max(peak - 1, previous_end + 1); i <= std::min(bin_count_ - 1, peak + 1);
           ++i)
        harmonic_power += power_[i];
      previous_end = peak + 1;
    });
    comb.harmonic_share = std::clamp(harmonic_power / total_power_, 0.0, 1.0);
  }
  comb.found =
      comb.strength >= settings_.min_strength && comb.harmonic_count >= settings_.min_harmonics;
  if (comb.found) {
    comb.fundamental_hz = fundamental_hz;
  } else {
    comb.harmonic_share = 0.0;
  }
  return comb;
}

HarmonicComb HarmonicCombDetector::analyse(std::span<const double> power) {
  autocorrelate(power, autocorrelation_);
  return find(autocorrelation_);
}

// A comb is found with min_harmonics lines, each a bin standing line_salience_db over its
// envelope; the lines' search windows (a quarter spacing, at least one bin, either side) overlap
// only at spacings under four bins, and then a bin is in at most two. So a spectrum with fewer
// than min_harmonics / 2 such bins holds no comb, and the autocorrelation, most of the cost, is
// skipped: the node asks this of every frame whose search ends under the floor, and a frame of
// noise has no line.
HarmonicComb HarmonicCombDetector::detect(std::span<const double> power) {
  const int salient = measure_salience(power);
  if (!valid_ || 2 * salient < settings_.min_harmonics) return HarmonicComb{};
  autocorrelate_salience(autocorrelation_);
  const HarmonicComb comb = find(autocorrelation_);
  return comb.found ? comb : HarmonicComb{};
}

}  // namespace dronetrack::doa
