#include "doa/array_health.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include <Eigen/SVD>

#include "common/statistics.hpp"

namespace dronetrack::doa {

namespace {

// Raised problems one observe() can hold per problem and channel (a frame judges each check at
// most once, so one suffices; the rest is slack for a node that skips clear_events()).
constexpr std::size_t kEventsPerProblem = 4;

// Median of `values` (reordered); 0 for none.
double median_of(std::span<double> values) {
  return values.empty() ? 0.0 : median_in_place(values);
}

}  // namespace

const char* to_string(ArrayProblem problem) {
  switch (problem) {
    case ArrayProblem::level_imbalance:
      return "level_imbalance";
    case ArrayProblem::dead:
      return "dead";
    case ArrayProblem::polarity_flipped:
      return "polarity_flipped";
    case ArrayProblem::closure:
      return "closure";
    case ArrayProblem::skew:
      return "skew";
    case ArrayProblem::swapped:
      return "swapped";
  }
  return "unknown";
}

PairPeak correlation_extremes(std::span<const double> correlation) {
  PairPeak extremes;
  for (const double value : correlation) {
    extremes.highest = std::max(extremes.highest, value);
    extremes.lowest = std::min(extremes.lowest, value);
  }
  return extremes;
}

namespace {
double magnitude(const PairPeak& pair) { return std::max(pair.highest, -pair.lowest); }
// The delay closure and the fit take: the source's own when measured.
double source_delay_s(const PairPeak& pair) {
  return std::isfinite(pair.source_tdoa_s) ? pair.source_tdoa_s : pair.tdoa_s;
}
}  // namespace

ArrayHealth::ArrayHealth(const ArrayGeometry& geometry, double speed_of_sound_mps, double hop_s,
                         const ArrayHealthSettings& settings)
    : channels_(static_cast<int>(geometry.mic_count())),
      pairs_(channels_ * (channels_ - 1) / 2),
      speed_of_sound_mps_(speed_of_sound_mps),
      settings_(settings) {
  auto fail = [](const std::string& what) { throw std::invalid_argument("ArrayHealth: " + what); };
  if (channels_ < 2 || channels_ > 8) fail("needs 2 to 8 mics");
  if (!(speed_of_sound_mps > 0.0)) fail("speed_of_sound_mps must be > 0");
  if (!(hop_s > 0.0)) fail("hop_s must be > 0");
  if (!(settings.level_stretch_s > 0.0)) fail("level_stretch_s must be > 0");
  if (!(settings.imbalance_db > 0.0)) fail("imbalance_db must be > 0");
  if (!(settings.dead_level_db < -settings.imbalance_db))
    fail("dead_level_db must be below -imbalance_db");
  if (!(settings.coherent_peak > 0.0 && settings.coherent_peak < 1.0))
    fail("coherent_peak must be in (0, 1)");
  if (!(settings.incoherent_ratio > 0.0 && settings.incoherent_ratio < 1.0))
    fail("incoherent_ratio must be in (0, 1)");
  if (!(settings.sign_dominance >= 1.0)) fail("sign_dominance must be >= 1");
  if (settings.judge_source_frames < 2) fail("judge_source_frames must be >= 2");
  if (!(settings.problem_share > 0.5 && settings.problem_share <= 1.0))
    fail("problem_share must be in (0.5, 1]");
  if (settings.closure_window_frames < 3) fail("closure_window_frames must be >= 3");
  if (settings.closure_persistence < 1) fail("closure_persistence must be >= 1");
  if (!(settings.closure_us > 0.0) || !(settings.frame_closure_us > 0.0))
    fail("closure_us and frame_closure_us must be > 0");
  if (!(settings.skew_sigmas > 0.0) || !(settings.min_skew_us > 0.0) ||
      !(settings.skew_window_s > 0.0) || !(settings.skew_prior_us > 0.0) ||
      !(settings.min_skew_frames >= 1.0))
    fail(
        "skew_sigmas, min_skew_us, skew_window_s, skew_prior_us must be > 0 and "
        "min_skew_frames >= 1");
  if (settings.skew_sectors < 2 || settings.min_skew_sectors < 1 ||
      settings.min_skew_sectors > settings.skew_sectors)
    fail("skew_sectors must be >= 2 and min_skew_sectors in [1, skew_sectors]");
  if (!(settings.rewarn_s >= 0.0)) fail("rewarn_s must be >= 0");
  if (!(settings.min_swap_frames >= 1.0) || !(settings.swap_evidence_us > 0.0) ||
      !(settings.swap_misfit_ratio > 0.0 && settings.swap_misfit_ratio < 1.0))
    fail("min_swap_frames must be >= 1, swap_evidence_us > 0 and swap_misfit_ratio in (0, 1)");

  const auto n = static_cast<std::size_t>(channels_);
  for (int i = 0; i < channels_; ++i)
    for (int j = i + 1; j < channels_; ++j) pair_mics_.push_back({i, j});
  auto pair_index = [&](int i, int j) { return i * (2 * channels_ - i - 1) / 2 + (j - i - 1); };
  for (int i = 0; i < channels_; ++i)
    for (int j = i + 1; j < channels_; ++j)
      for (int k = j + 1; k < channels_; ++k) {
        triples_.push_back({i, j, k});
        triple_pairs_.push_back({pair_index(i, j), pair_index(j, k), pair_index(i, k)});
      }
  channels_health_.assign(n, ArrayChannelHealth{});
  states_.assign(n, {});
  events_.reserve(n * kArrayProblemCount * kEventsPerProblem);
  power_sums_.assign(n, 0.0);
  level_stretch_frames_ =
      std::max(1, static_cast<int>(std::lround(settings.level_stretch_s / hop_s)));
  const auto window = static_cast<std::size_t>(settings.closure_window_frames);
  scratch_.assign(std::max({n, static_cast<std::size_t>(pairs_), window}), 0.0);
  incoherent_frames_.assign(n, 0);
  previous_skewed_.assign(n, 0);
  level_dead_.assign(n, 0);
  incoherent_dead_.assign(n, 0);
  coherent_frames_.assign(static_cast<std::size_t>(pairs_), 0);
  negative_frames_.assign(static_cast<std::size_t>(pairs_), 0);
  closure_ring_.assign(triples_.size() * window, 0.0);
  closure_count_.assign(triples_.size(), 0);
  closure_next_.assign(triples_.size(), 0);
  closure_failing_runs_.assign(triples_.size(), 0);
  fit_ring_.assign(window, 0.0);

  // The delay fit needs the slowness in three dimensions: a planar or linear array leaves it out.
  geometry_.resize(pairs_, 3);
  for (int p = 0; p < pairs_; ++p) {
    const auto [i, j] = pair_mics_[static_cast<std::size_t>(p)];
    geometry_.row(p) = (geometry.mics_m[static_cast<std::size_t>(j)] -
                        geometry.mics_m[static_cast<std::size_t>(i)])
                           .transpose();
  }
  const Eigen::MatrixXd pair_vectors = geometry_;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(pair_vectors);
  const Eigen::VectorXd singular = svd.singularValues();
  fit_possible_ = singular.size() == 3 && singular(0) > 0.0 && singular(2) > 1e-3 * singular(0);
  frame_tdoas_.setZero(pairs_);
  if (fit_possible_) {
    const Eigen::Matrix3d normal = geometry_.transpose() * geometry_;
    geometry_inverse_ = normal.inverse() * geometry_.transpose();
    ChannelDelayFit::Settings fit;
    fit.window_s = settings.skew_window_s;
    fit.prior_us = settings.skew_prior_us;
    fit.sectors = settings.skew_sectors;
    delay_fit_.emplace(geometry_, channels_, speed_of_sound_mps, hop_s, fit);
  }
  forgetting_ = std::exp(-hop_s / settings.skew_window_s);

  // Each transposition's relabelling of the pairs: recorded pair (i, j) holds the delay of the
  // mics (s(i), s(j)), s the swap, so that pair's delay goes to their pair with its sign.
  for (int a = 0; a < channels_; ++a)
    for (int b = a + 1; b < channels_; ++b) transpositions_.push_back({a, b});
  relabel_source_.assign(transpositions_.size() * static_cast<std::size_t>(pairs_), 0);
  relabel_sign_.assign(relabel_source_.size(), 1.0);
  for (std::size_t t = 0; t < transpositions_.size(); ++t) {
    // Plain copies, not a structured binding: clang 14 (the fuzz build) cannot capture those.
    const int a = transpositions_[t][0], b = transpositions_[t][1];
    auto swapped = [a, b](int mic) { return mic == a ? b : mic == b ? a : mic; };
    for (int p = 0; p < pairs_; ++p) {
      const auto [i, j] = pair_mics_[static_cast<std::size_t>(p)];
      const int x = swapped(i), y = swapped(j);
      const std::size_t slot = t * static_cast<std::size_t>(pairs_) +
                               static_cast<std::size_t>(pair_index(std::min(x, y), std::max(x, y)));
      relabel_source_[slot] = p;
      relabel_sign_[slot] = x < y ? 1.0 : -1.0;
    }
  }
  swap_signature_us_.assign(transpositions_.size(), 0.0);
  swap_square_sums_.assign(transpositions_.size() + 1, 0.0);
  relabelled_.setZero(pairs_);
  if (!fit_possible_) return;
  // A swap's signature: its misfit on exact plane waves from directions spread evenly over the
  // sphere (a Fibonacci lattice).
  constexpr int kDirections = 256;
  const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int d = 0; d < kDirections; ++d) {
    const double z = 1.0 - (2.0 * d + 1.0) / kDirections;
    const double radius = std::sqrt(1.0 - z * z);
    const Eigen::Vector3d u(radius * std::cos(golden_angle * d),
                            radius * std::sin(golden_angle * d), z);
    frame_tdoas_.noalias() = geometry_ * (u / speed_of_sound_mps_);
    for (std::size_t t = 0; t < transpositions_.size(); ++t) {
      relabel(static_cast<int>(t), frame_tdoas_, relabelled_);
      swap_signature_us_[t] += plane_wave_misfit_square(relabelled_) / kDirections;
    }
  }
  for (double& signature : swap_signature_us_) signature = 1e6 * std::sqrt(signature);
}

int ArrayHealth::transposition_index(int a, int b) const {
  if (a == b || a < 0 || b < 0 || a >= channels_ || b >= channels_) return -1;
  const int low = std::min(a, b), high = std::max(a, b);
  return low * (2 * channels_ - low - 1) / 2 + (high - low - 1);
}

double ArrayHealth::swap_signature_us(int a, int b) const {
  const int t = transposition_index(a, b);
  return t < 0 ? 0.0 : swap_signature_us_[static_cast<std::size_t>(t)];
}

bool ArrayHealth::swap_observable(int a, int b) const {
  return fit_possible_ && swap_signature_us(a, b) >= settings_.swap_evidence_us;
}

void ArrayHealth::relabel(int transposition, const PairVector& tdoas, PairVector& out) const {
  const std::size_t base =
      static_cast<std::size_t>(transposition) * static_cast<std::size_t>(pairs_);
  for (int q = 0; q < pairs_; ++q) {
    const std::size_t slot = base + static_cast<std::size_t>(q);
    out(q) = relabel_sign_[slot] * tdoas(relabel_source_[slot]);
  }
}

double ArrayHealth::plane_wave_misfit_square(const PairVector& tdoas) const {
  const Eigen::Vector3d slowness = geometry_inverse_ * tdoas;
  const double norm = slowness.norm();
  if (!(norm > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  const PairVector misfit = tdoas - geometry_ * (slowness / (norm * speed_of_sound_mps_));
  return misfit.squaredNorm() / pairs_;
}

bool ArrayHealth::coherent_positive(const PairPeak& pair) const {
  return pair.highest >= settings_.coherent_peak && pair.highest >= -pair.lowest &&
         std::isfinite(pair.tdoa_s);
}

// A band-pass correlation's first side lobes are negative and, when the band is narrow (the
// SNR weights leave a rotor's few strongest lines), nearly as deep as the main lobe is high:
// echoes and a second source then tip one over the other on a clean pair. Only a clear winner
// tells the sign.
int ArrayHealth::lobe_sign(const PairPeak& pair) const {
  if (magnitude(pair) < settings_.coherent_peak) return 0;
  if (pair.highest >= -settings_.sign_dominance * pair.lowest) return 1;
  if (-pair.lowest >= settings_.sign_dominance * pair.highest) return -1;
  return 0;
}

void ArrayHealth::observe(double time_s, std::span<const double> channel_power,
                          std::span<const PairPeak> pairs, bool source, bool single_source) {
  if (channel_power.size() == static_cast<std::size_t>(channels_))
    observe_levels(time_s, channel_power);
  if (!source || pairs.size() != static_cast<std::size_t>(pairs_)) return;
  // A source for these checks: enough pairs hear it that every pair of all mics but one could
  // be among them (a dead or flipped mic leaves those).
  const int needed = std::max(1, (channels_ - 1) * (channels_ - 2) / 2);
  int coherent = 0;
  for (const PairPeak& pair : pairs)
    if (magnitude(pair) >= settings_.coherent_peak) ++coherent;
  if (coherent < needed) return;
  observe_coherence(time_s, pairs);
  if (single_source) observe_closure(pairs);
  if (++closure_new_frames_ < settings_.judge_source_frames) return;
  closure_new_frames_ = 0;
  judge_delays(time_s);
}

void ArrayHealth::judge_delays(double time_s) {
  judge_closure(time_s);
  if (!fit_possible_) return;
  judge_swaps(time_s);
  judge_skew(time_s);
}

void ArrayHealth::observe_levels(double time_s, std::span<const double> channel_power) {
  for (int c = 0; c < channels_; ++c) {
    const double power = channel_power[static_cast<std::size_t>(c)];
    if (std::isfinite(power) && power > 0.0) power_sums_[static_cast<std::size_t>(c)] += power;
  }
  if (++level_frames_ < level_stretch_frames_) return;
  const std::span<double> levels(scratch_.data(), static_cast<std::size_t>(channels_));
  std::array<double, 8> own{};  // the levels in channel order; median_of reorders `levels`
  for (int c = 0; c < channels_; ++c) {
    const auto index = static_cast<std::size_t>(c);
    own[index] = 10.0 * std::log10(std::max(power_sums_[index] / level_frames_, 1e-30));
    levels[index] = own[index];
  }
  const double median_db = median_of(levels);
  level_frames_ = 0;
  std::fill(power_sums_.begin(), power_sums_.end(), 0.0);
  // No signal in the band on most channels: nothing to compare (ChannelHealth says silent).
  if (median_db <= -290.0) return;
  for (int c = 0; c < channels_; ++c) {
    const auto index = static_cast<std::size_t>(c);
    const double offset_db = own[index] - median_db;
    channels_health_[index].level_offset_db = offset_db;
    const bool dead = offset_db < settings_.dead_level_db;
    level_dead_[index] = dead ? 1 : 0;
    // A dead mic's level says it is dead, not imbalanced.
    update(c, ArrayProblem::level_imbalance,
           !dead && incoherent_dead_[index] == 0 && std::fabs(offset_db) > settings_.imbalance_db,
           time_s, 0.0);
    update(c, ArrayProblem::dead, dead || incoherent_dead_[index] != 0, time_s, 0.0);
  }
}

void ArrayHealth::observe_coherence(double time_s, std::span<const PairPeak> pairs) {
  ++source_frames_;
  for (int p = 0; p < pairs_; ++p) {
    const int sign = lobe_sign(pairs[static_cast<std::size_t>(p)]);
    if (sign == 0) continue;
    ++coherent_frames_[static_cast<std::size_t>(p)];
    if (sign < 0) ++negative_frames_[static_cast<std::size_t>(p)];
  }
  // A mic is incoherent when its best pair is far under what the pairs without it reach.
  if (channels_ >= 3) {
    for (int c = 0; c < channels_; ++c) {
      double best = 0.0;
      std::size_t others = 0;
      for (int p = 0; p < pairs_; ++p) {
        const auto [i, j] = pair_mics_[static_cast<std::size_t>(p)];
        const double size = magnitude(pairs[static_cast<std::size_t>(p)]);
        if (i == c || j == c)
          best = std::max(best, size);
        else
          scratch_[others++] = size;
      }
      const double typical = median_of(std::span<double>(scratch_.data(), others));
      if (typical >= settings_.coherent_peak && best < settings_.incoherent_ratio * typical)
        ++incoherent_frames_[static_cast<std::size_t>(c)];
    }
  }
  if (source_frames_ < settings_.judge_source_frames) return;
  const double share_needed = settings_.problem_share * source_frames_;
  for (int c = 0; c < channels_; ++c) {
    const auto index = static_cast<std::size_t>(c);
    const double incoherent_share = static_cast<double>(incoherent_frames_[index]) / source_frames_;
    incoherent_dead_[index] = incoherent_frames_[index] >= share_needed ? 1 : 0;
    update(c, ArrayProblem::dead, level_dead_[index] != 0 || incoherent_dead_[index] != 0, time_s,
           incoherent_share);
    if (incoherent_dead_[index] != 0) update(c, ArrayProblem::level_imbalance, false, time_s, 0.0);
    // Flipped: most of its pairs that heard the source on most of the frames did so negative. A
    // two-mic array cannot tell which of its mics is flipped.
    if (channels_ < 3) continue;
    // One flipped mic turns the signs of its own pairs only: most of them negative, most of
    // the others positive. All pairs negative is the scene (a band whose side lobes rival its
    // main lobe, an echo adding into one), not a mic.
    int judged = 0, negative = 0, others_judged = 0, others_positive = 0;
    double negative_share = 0.0;
    for (int p = 0; p < pairs_; ++p) {
      const auto [i, j] = pair_mics_[static_cast<std::size_t>(p)];
      const auto pair = static_cast<std::size_t>(p);
      if (2 * coherent_frames_[pair] < source_frames_) continue;
      const double share = static_cast<double>(negative_frames_[pair]) / coherent_frames_[pair];
      if (i != c && j != c) {
        ++others_judged;
        if (share <= 1.0 - settings_.problem_share) ++others_positive;
        continue;
      }
      ++judged;
      if (share >= settings_.problem_share) {
        ++negative;
        negative_share += share;
      }
    }
    if (judged == 0 || others_judged == 0) continue;  // not heard enough to say
    const bool flipped = 2 * negative > judged && 2 * others_positive > others_judged;
    update(c, ArrayProblem::polarity_flipped, flipped, time_s,
           negative > 0 ? negative_share / negative : 0.0);
  }
  source_frames_ = 0;
  std::fill(incoherent_frames_.begin(), incoherent_frames_.end(), 0);
  std::fill(coherent_frames_.begin(), coherent_frames_.end(), 0);
  std::fill(negative_frames_.begin(), negative_frames_.end(), 0);
}

void ArrayHealth::observe_closure(std::span<const PairPeak> pairs) {
  const auto window = static_cast<std::size_t>(settings_.closure_window_frames);
  double frame_closure_s = 0.0;
  bool all_positive = true;
  for (std::size_t t = 0; t < triples_.size(); ++t) {
    const auto [ij, jk, ik] = triple_pairs_[t];
    const PairPeak& a = pairs[static_cast<std::size_t>(ij)];
    const PairPeak& b = pairs[static_cast<std::size_t>(jk)];
    const PairPeak& c = pairs[static_cast<std::size_t>(ik)];
    // A negative main lobe (a flipped mic) gives no lag to add: its peak is a side lobe.
    if (!coherent_positive(a) || !coherent_positive(b) || !coherent_positive(c)) {
      all_positive = false;
      continue;
    }
    const double closure_s = source_delay_s(a) + source_delay_s(b) - source_delay_s(c);
    frame_closure_s = std::max(frame_closure_s, std::fabs(closure_s));
    closure_ring_[t * window + static_cast<std::size_t>(closure_next_[t])] = closure_s;
    closure_next_[t] = (closure_next_[t] + 1) % settings_.closure_window_frames;
    closure_count_[t] = std::min(closure_count_[t] + 1, settings_.closure_window_frames);
  }
  for (const PairPeak& pair : pairs) all_positive = all_positive && coherent_positive(pair);
  if (fit_possible_ && all_positive && frame_closure_s <= 1e-6 * settings_.frame_closure_us)
    observe_fit(pairs);
}

// One frame of the plane-wave fits: the swap check on the first look's delays, the delay fit
// (ChannelDelayFit) on the source's.
void ArrayHealth::observe_fit(std::span<const PairPeak> pairs) {
  for (int p = 0; p < pairs_; ++p) frame_tdoas_(p) = pairs[static_cast<std::size_t>(p)].tdoa_s;
  const double first_look_square = plane_wave_misfit_square(frame_tdoas_);
  if (std::isfinite(first_look_square)) observe_swaps(first_look_square);
  for (int p = 0; p < pairs_; ++p)
    frame_tdoas_(p) = source_delay_s(pairs[static_cast<std::size_t>(p)]);
  // The LS DOA's misfit as the node measures it, before any delay is taken out.
  const double wired_square = plane_wave_misfit_square(frame_tdoas_);
  if (!std::isfinite(wired_square)) return;
  fit_ring_[static_cast<std::size_t>(fit_next_)] = std::sqrt(wired_square);
  fit_next_ = (fit_next_ + 1) % settings_.closure_window_frames;
  fit_count_ = std::min(fit_count_ + 1, settings_.closure_window_frames);
  delay_fit_->observe(frame_tdoas_);
}

// Each observable swap's misfit on this frame's first-look delays (frame_tdoas_), beside the
// wiring's.
void ArrayHealth::observe_swaps(double wired_square) {
  swap_frames_ = forgetting_ * swap_frames_ + 1.0;
  swap_square_sums_[0] = forgetting_ * swap_square_sums_[0] + wired_square;
  for (std::size_t t = 0; t < transpositions_.size(); ++t) {
    double& sum = swap_square_sums_[t + 1];
    sum *= forgetting_;
    if (swap_signature_us_[t] < settings_.swap_evidence_us) continue;
    relabel(static_cast<int>(t), frame_tdoas_, relabelled_);
    const double square = plane_wave_misfit_square(relabelled_);
    // A relabelling that leaves no slowness explains nothing: as bad as the wiring.
    sum += std::isfinite(square) ? square : wired_square;
  }
}

// A swap is said when relabelling its two channels lowers the RMS misfit over the recent source
// frames to at most swap_misfit_ratio of the wiring's, by at least swap_evidence_us, and the
// same swap wins two judgements in a row. A wiring that fits leaves no swap room to win: the
// misfit it shows is the GCC noise and the model's (echo, near field), which no relabelling
// removes; a swap's misfit is its signature, which the right relabelling removes entirely.
void ArrayHealth::judge_swaps(double time_s) {
  if (swap_frames_ < settings_.min_swap_frames) return;
  const double wired_us = 1e6 * std::sqrt(swap_square_sums_[0] / swap_frames_);
  int best = -1;
  double best_us = wired_us;
  for (std::size_t t = 0; t < transpositions_.size(); ++t) {
    if (swap_signature_us_[t] < settings_.swap_evidence_us) continue;
    const double misfit_us = 1e6 * std::sqrt(swap_square_sums_[t + 1] / swap_frames_);
    if (misfit_us < best_us) {
      best = static_cast<int>(t);
      best_us = misfit_us;
    }
  }
  const bool decisive = best >= 0 && best_us <= settings_.swap_misfit_ratio * wired_us &&
                        wired_us - best_us >= settings_.swap_evidence_us;
  const int candidate = decisive ? best : -1;
  swap_flagged_ = candidate >= 0 && candidate == swap_candidate_ ? candidate : -1;
  swap_candidate_ = candidate;
  for (int c = 0; c < channels_; ++c) {
    const bool flagged =
        swap_flagged_ >= 0 && (transpositions_[static_cast<std::size_t>(swap_flagged_)][0] == c ||
                               transpositions_[static_cast<std::size_t>(swap_flagged_)][1] == c);
    const bool first = flagged && transpositions_[static_cast<std::size_t>(swap_flagged_)][0] == c;
    if (first) {
      swap_event_ = {transpositions_[static_cast<std::size_t>(swap_flagged_)][1], wired_us,
                     best_us};
    }
    // One line names both channels: the first raises it, the second carries the flag.
    update(c, ArrayProblem::swapped, flagged, time_s, 0.0, first || !flagged);
  }
}

// A triple fails when its running median closure is off zero; a channel is named when it is the
// only one every failing triple holds (and at least two fail).
void ArrayHealth::judge_closure(double time_s) {
  const auto window = static_cast<std::size_t>(settings_.closure_window_frames);
  closure_residual_us_ = 0.0;
  std::array<int, 8> failing_of{};
  int failing = 0;
  bool judged = false;
  for (std::size_t t = 0; t < triples_.size(); ++t) {
    if (2 * closure_count_[t] < settings_.closure_window_frames) continue;
    judged = true;
    const auto count = static_cast<std::size_t>(closure_count_[t]);
    std::copy_n(closure_ring_.begin() + static_cast<std::ptrdiff_t>(t * window), count,
                scratch_.begin());
    const double median_us = 1e6 * median_of(std::span<double>(scratch_.data(), count));
    closure_residual_us_ = std::max(closure_residual_us_, std::fabs(median_us));
    // A stretch of frames whose pairs follow different sources can hold a median off for a
    // judgement or two: a triple fails when it stays off.
    int& runs = closure_failing_runs_[t];
    runs = std::fabs(median_us) > settings_.closure_us ? runs + 1 : 0;
    if (runs < settings_.closure_persistence) continue;
    ++failing;
    for (const int mic : triples_[t]) ++failing_of[static_cast<std::size_t>(mic)];
  }
  if (fit_count_ > 0) {
    std::copy_n(fit_ring_.begin(), fit_count_, scratch_.begin());
    fit_residual_us_ =
        1e6 * median_of(std::span<double>(scratch_.data(), static_cast<std::size_t>(fit_count_)));
  }
  if (!judged || channels_ < 4) return;
  int common = 0;
  for (int c = 0; c < channels_; ++c)
    if (failing >= 2 && failing_of[static_cast<std::size_t>(c)] == failing) ++common;
  for (int c = 0; c < channels_; ++c) {
    const bool named = common == 1 && failing_of[static_cast<std::size_t>(c)] == failing;
    update(c, ArrayProblem::closure, named, time_s, 0.0);
  }
}

// A channel is skewed when its fitted delay offset is skew_sigmas of its cluster-robust std from
// 0 and over min_skew_us, once the fit has seen min_skew_sectors direction sectors (fewer leave a
// delay indistinguishable from a change of direction or of the slowness's scale: unexcited, so
// unsaid), on two judgements in a row.
void ArrayHealth::judge_skew(double time_s) {
  // Solved at every judgement, judged or not: each solve is the point the next frames are
  // linearised at, and frames taken far from the answer bias it by the square of the distance.
  delay_fit_->solve();
  if (delay_fit_->frames() < settings_.min_skew_frames) return;
  // Each sector is one look (its frames share their biases): twice as many looks as free
  // parameters at least, or the cluster-robust std is itself too uncertain to judge by.
  const bool excited = delay_fit_->sectors_seen() >=
                       std::max(settings_.min_skew_sectors, 2 * delay_fit_->free_parameters());
  delay_sectors_ = delay_fit_->sectors_seen();
  for (int c = 0; c < channels_; ++c) {
    const auto index = static_cast<std::size_t>(c);
    const ChannelDelayFit::ChannelDelay& delay = delay_fit_->channel_delays()[index];
    ArrayChannelHealth& health = channels_health_[index];
    // A swap's misfit is not a delay: while one is said, the fit says no skew.
    const bool over = excited && swap_flagged_ < 0 &&
                      std::fabs(delay.offset_us) > settings_.skew_sigmas * delay.std_us &&
                      std::fabs(delay.offset_us) > settings_.min_skew_us;
    // Said when over on two judgements in a row that agree to a quarter of the minimum (the
    // linearisation has settled).
    const bool settled =
        std::fabs(delay.offset_us - health.delay_offset_us) < 0.25 * settings_.min_skew_us;
    const bool skewed = over && settled && previous_skewed_[index] != 0;
    previous_skewed_[index] = over ? 1 : 0;
    health.delay_offset_us = delay.offset_us;
    health.delay_std_us = excited ? delay.std_us : std::numeric_limits<double>::infinity();
    update(c, ArrayProblem::skew, skewed, time_s, 0.0);
  }
}

void ArrayHealth::update(int channel, ArrayProblem problem, bool present, double time_s,
                         double share, bool announce) {
  ProblemState& state =
      states_[static_cast<std::size_t>(channel)][static_cast<std::size_t>(problem)];
  ArrayChannelHealth& health = channels_health_[static_cast<std::size_t>(channel)];
  if (!present) {
    state.present = false;
    state.announced = false;
    health.problems &= static_cast<ArrayFlags>(~array_flag(problem));
    return;
  }
  state.present = true;
  health.problems |= array_flag(problem);
  health.problems_seen |= array_flag(problem);
  if (!announce || state.announced || time_s - state.last_raised_s < settings_.rewarn_s) return;
  state.announced = true;
  state.last_raised_s = time_s;
  if (events_.size() == events_.capacity()) return;  // never allocates
  ArrayHealthEvent event;
  event.channel = channel;
  event.problem = problem;
  event.time_s = time_s;
  event.level_offset_db = health.level_offset_db;
  event.delay_offset_us = health.delay_offset_us;
  event.delay_std_us = health.delay_std_us;
  event.delay_sectors = delay_sectors_;
  event.closure_residual_us = closure_residual_us_;
  event.share = share;
  if (problem == ArrayProblem::swapped) {
    event.other_channel = swap_event_.other_channel;
    event.wired_misfit_us = swap_event_.wired_misfit_us;
    event.swapped_misfit_us = swap_event_.swapped_misfit_us;
  }
  events_.push_back(event);
}

}  // namespace dronetrack::doa
