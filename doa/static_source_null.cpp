#include "doa/static_source_null.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <Eigen/Eigenvalues>

namespace dronetrack::doa {

namespace {
// A nulled source is still heard when the bins matching it carry this share of the band's
// cross-power; noise alone matches ~5 % of the bins at the default threshold.
constexpr double kPresentShare = 0.15;
// Of the frames since a tentative source first appeared, this share must have it as the peak.
constexpr double kMinHitShare = 0.5;
// A per-pair peak weaker than this is no observation of anything.
constexpr double kMinPeakValue = 0.1;
// ... and a slot's peak at least this share of the pair's strongest to count as heard.
constexpr double kMinRelativePeak = 0.3;
// A bin's averaged phasor at least this long is the source's steady phase (adapt()).
constexpr double kSteadyBin = 0.5;
constexpr double kMaxBend = 0.5;  // cos(60 deg)
}  // namespace

StaticNullSettings static_null_settings(const DoaParams& params, double hop_s,
                                        double speed_of_sound_mps) {
  StaticNullSettings settings;
  settings.hop_s = hop_s;
  settings.learn_s = params.static_null_learn_s;
  settings.forget_s = params.static_null_forget_s;
  settings.max_elevation_deg = params.static_null_max_elevation_deg;
  settings.tolerance_s = params.static_null_tolerance_us * 1e-6;
  settings.max_sources = params.static_null_max_sources;
  settings.speed_of_sound_mps = speed_of_sound_mps;
  return settings;
}

StaticSourceNull::StaticSourceNull(const ArrayGeometry& geometry, const GccPhat& gcc,
                                   StaticNullSettings settings)
    : settings_(settings),
      pair_count_(gcc.pair_count()),
      band_bins_(gcc.band_bin_count()),
      band_(gcc.band()),
      bin_omega_(gcc.bin_omega_rad_per_s()) {
  if (pair_count_ > kMaxPairs)
    throw std::invalid_argument("StaticSourceNull: at most 28 mic pairs (8 mics)");
  if (settings_.max_sources < 0 || settings_.max_sources > kSlots - 2)
    throw std::invalid_argument("StaticSourceNull: max_sources must be in [0, 4]");
  if (!(settings_.hop_s > 0.0) || !(settings_.learn_s > 0.0) || !(settings_.forget_s > 0.0) ||
      !(settings_.tolerance_s > 0.0) || !(settings_.speed_of_sound_mps > 0.0))
    throw std::invalid_argument("StaticSourceNull: times, tolerance and c must be > 0");
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  pair_index_.fill(-1);
  mic_count_ = static_cast<int>(geometry.mic_count());
  if (mic_count_ > kMaxMics) throw std::invalid_argument("StaticSourceNull: at most 8 mics");
  for (int p = 0; p < pair_count_; ++p) {
    const MicPairSpec& pair = gcc.pair_spec(p);
    pair_index_[static_cast<std::size_t>(pair.mic_i * kMaxMics + pair.mic_j)] = p;
    const Eigen::Vector3d baseline = geometry.mics_m[static_cast<std::size_t>(pair.mic_i)] -
                                     geometry.mics_m[static_cast<std::size_t>(pair.mic_j)];
    pair_baselines_m_.push_back(baseline);
    normal += baseline * baseline.transpose();
  }
  // tau_p = -u . d_p / c: u = -c (D^T D)^+ D^T tau over the directions the geometry resolves.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(normal);
  const double largest = eigen.eigenvalues().maxCoeff();
  for (int e = 0; e < 3; ++e) {
    const double value = eigen.eigenvalues()(e);
    if (value > 1e-6 * largest) {
      ++geometry_rank_;
      normal_inverse_ +=
          eigen.eigenvectors().col(e) * eigen.eigenvectors().col(e).transpose() / value;
    } else {
      plane_normal_ = eigen.eigenvectors().col(e);
    }
  }
  signatures_.assign(static_cast<std::size_t>(settings_.max_sources),
                     std::vector<std::complex<double>>(
                         static_cast<std::size_t>(pair_count_) * band_bins_, {0.0, 0.0}));
  averages_ = signatures_;
  models_ = signatures_;
  signature_used_.assign(static_cast<std::size_t>(settings_.max_sources), false);
  scores_.assign(static_cast<std::size_t>(band_bins_), 0.0);
  model_scores_.assign(static_cast<std::size_t>(band_bins_), 0.0);
  bin_power_.assign(static_cast<std::size_t>(band_bins_), 0.0);
  frame_tdoas_.assign(static_cast<std::size_t>(pair_count_), 0.0);
  slot_tdoas_.assign(static_cast<std::size_t>(pair_count_), 0.0);
}

int StaticSourceNull::nulled_count() const {
  return static_cast<int>(std::count_if(slots_.begin(), slots_.end(),
                                        [](const Slot& s) { return s.state == State::nulled; }));
}

int StaticSourceNull::nulled_tdoas(int nulled_index, std::span<double> tdoas_s) const {
  int seen = 0;
  for (const Slot& slot : slots_) {
    if (slot.state != State::nulled) continue;
    if (seen++ != nulled_index) continue;
    const int count = std::min(pair_count_, static_cast<int>(tdoas_s.size()));
    std::copy_n(slot.tdoa_s.begin(), count, tdoas_s.begin());
    return count;
  }
  return 0;
}

void StaticSourceNull::mask(double time_s, GccPhat& gcc) {
  dropped_share_ = 0.0;
  if (nulled_count() == 0) return;
  std::fill(bin_power_.begin(), bin_power_.end(), 0.0);
  for (int p = 0; p < pair_count_; ++p) {
    const std::span<const double> magnitude = gcc.magnitudes(p);
    for (int k = 0; k < band_bins_; ++k)
      bin_power_[static_cast<std::size_t>(k)] += magnitude[static_cast<std::size_t>(k)];
  }
  double total_power = 0.0;
  for (const double power : bin_power_) total_power += power;
  const std::span<std::uint8_t> keep = gcc.bin_keep();
  const double threshold = settings_.match_threshold * pair_count_;
  for (Slot& slot : slots_) {
    if (slot.state != State::nulled) continue;
    const std::size_t which = static_cast<std::size_t>(slot.signature);
    std::fill(scores_.begin(), scores_.end(), 0.0);
    std::fill(model_scores_.begin(), model_scores_.end(), 0.0);
    for (int p = 0; p < pair_count_; ++p) {
      const std::span<const std::complex<double>> phasor = gcc.phasors(p);
      const std::complex<double>* signature =
          signatures_[which].data() + static_cast<std::ptrdiff_t>(p) * band_bins_;
      const std::complex<double>* model =
          models_[which].data() + static_cast<std::ptrdiff_t>(p) * band_bins_;
      for (int k = 0; k < band_bins_; ++k) {
        const std::complex<double> w = phasor[static_cast<std::size_t>(k)];
        scores_[static_cast<std::size_t>(k)] += (w * signature[k]).real();
        model_scores_[static_cast<std::size_t>(k)] += (w * model[k]).real();
      }
    }
    if (settings_.adapt_bins) adapt(slot.signature, gcc);
    // Whether the source is still there is judged on the pure delay model: the adapted
    // signature could otherwise keep itself alive on another source's steady bins.
    double matched_power = 0.0;
    for (int k = 0; k < band_bins_; ++k) {
      if (model_scores_[static_cast<std::size_t>(k)] >= threshold)
        matched_power += bin_power_[static_cast<std::size_t>(k)];
      if (scores_[static_cast<std::size_t>(k)] >= threshold) keep[static_cast<std::size_t>(k)] = 0;
    }
    if (total_power > 0.0 && matched_power >= kPresentShare * total_power)
      slot.last_heard_s = time_s;
    if (time_s - slot.last_heard_s > settings_.forget_s) {
      signature_used_[static_cast<std::size_t>(slot.signature)] = false;
      slot = Slot{};
    }
  }
  int dropped = 0;
  for (const std::uint8_t kept : keep) dropped += kept == 0 ? 1 : 0;
  dropped_share_ = static_cast<double>(dropped) / band_bins_;
}

bool StaticSourceNull::heard(const GccPhat& gcc, const Slot& slot) {
  // Heard when every pair's correlation has a clear local peak at the slot's TDOAs, even if
  // another source is the strongest in this frame (a drone passing, at an array where it and
  // the static source are about as loud). The grid look-up rules most slots out cheaply.
  for (int p = 0; p < pair_count_; ++p) {
    const double floor = std::max(kMinPeakValue, kMinRelativePeak * gcc.pair(p).peak.value);
    if (gcc.grid_value(p, slot.tdoa_s[static_cast<std::size_t>(p)]) < 0.5 * floor) return false;
  }
  for (int p = 0; p < pair_count_; ++p) {
    GccPeak peak;
    const double tau = slot.tdoa_s[static_cast<std::size_t>(p)];
    if (!gcc.refine(p, tau, peak) || std::abs(peak.lag_s - tau) > settings_.tolerance_s ||
        peak.value < std::max(kMinPeakValue, kMinRelativePeak * gcc.pair(p).peak.value))
      return false;
    slot_tdoas_[static_cast<std::size_t>(p)] = peak.lag_s;
  }
  return true;
}

bool StaticSourceNull::matches(const Slot& slot, std::span<const double> tdoas_s) const {
  for (int p = 0; p < pair_count_; ++p)
    if (std::abs(tdoas_s[static_cast<std::size_t>(p)] - slot.tdoa_s[static_cast<std::size_t>(p)]) >
        settings_.tolerance_s)
      return false;
  return true;
}

void StaticSourceNull::observe(double time_s, const GccPhat& gcc, bool usable) {
  if (!usable) return;
  bool sharp = true;
  for (int p = 0; p < pair_count_; ++p) {
    const PairCorrelation& pair = gcc.pair(p);
    sharp = sharp && pair.peak.value >= kMinPeakValue;
    frame_tdoas_[static_cast<std::size_t>(p)] = pair.peak.lag_s;
  }
  Slot* matched = nullptr;  // the slot the frame's strongest peaks belong to
  for (Slot& slot : slots_) {
    if (slot.state == State::empty) continue;
    if (sharp && matched == nullptr && matches(slot, frame_tdoas_)) matched = &slot;
    if (slot.state == State::nulled) continue;
    ++slot.frames;
    if (!heard(gcc, slot)) continue;
    // Running mean over the first frames, then an average over ~learn_s: static sources do
    // not move, so the mean only sheds the per-frame noise.
    ++slot.hits;
    const double max_weight_frames = std::max(1.0, settings_.learn_s / settings_.hop_s);
    const double weight = 1.0 / std::min<double>(slot.hits, max_weight_frames);
    for (int p = 0; p < pair_count_; ++p)
      slot.tdoa_s[static_cast<std::size_t>(p)] +=
          weight *
          (slot_tdoas_[static_cast<std::size_t>(p)] - slot.tdoa_s[static_cast<std::size_t>(p)]);
    slot.last_heard_s = time_s;
  }
  if (matched == nullptr && sharp && consistent(frame_tdoas_)) {
    // A new candidate takes a free slot, else the tentative one heard longest ago.
    Slot* target = nullptr;
    for (Slot& slot : slots_) {
      if (slot.state == State::empty) {
        target = &slot;
        break;
      }
      if (slot.state == State::tentative &&
          (target == nullptr || slot.last_heard_s < target->last_heard_s))
        target = &slot;
    }
    if (target != nullptr) {
      *target = Slot{};
      target->state = State::tentative;
      std::copy(frame_tdoas_.begin(), frame_tdoas_.end(), target->tdoa_s.begin());
      target->first_s = time_s;
      target->last_heard_s = time_s;
      target->hits = 1;
      target->frames = 1;
    }
  }
  for (Slot& slot : slots_) {
    if (slot.state == State::tentative || slot.state == State::sky) {
      const bool silent = time_s - slot.last_heard_s > settings_.forget_s;
      const bool intermittent = slot.state == State::tentative &&
                                slot.hits < kMinHitShare * slot.frames &&
                                time_s - slot.first_s >= settings_.learn_s;
      if (silent || intermittent) {
        slot = Slot{};
        continue;
      }
    }
    if (slot.state == State::tentative && time_s - slot.first_s >= settings_.learn_s) decide(slot);
  }
}

bool StaticSourceNull::consistent(std::span<const double> tdoas_s) const {
  // One source, any range: t_i - t_k = (t_i - t_j) + (t_j - t_k) for every mic triple. Peaks
  // of two sources mixed across pairs break it (by hundreds of microseconds, typically).
  // tau(a, b) = t_a - t_b from whichever of (a, b) / (b, a) is a pair; false if neither.
  const auto tau = [&](int a, int b, double& out) {
    const int forward = pair_index_[static_cast<std::size_t>(a * kMaxMics + b)];
    const int backward = pair_index_[static_cast<std::size_t>(b * kMaxMics + a)];
    if (forward >= 0) out = tdoas_s[static_cast<std::size_t>(forward)];
    if (forward < 0 && backward >= 0) out = -tdoas_s[static_cast<std::size_t>(backward)];
    return forward >= 0 || backward >= 0;
  };
  for (int i = 0; i < mic_count_; ++i)
    for (int j = i + 1; j < mic_count_; ++j)
      for (int k = j + 1; k < mic_count_; ++k) {
        double ij = 0.0;
        double jk = 0.0;
        double ik = 0.0;
        if (!tau(i, j, ij) || !tau(j, k, jk) || !tau(i, k, ik)) continue;
        if (std::abs(ij + jk - ik) > 2.0 * settings_.tolerance_s) return false;
      }
  return true;
}

void StaticSourceNull::decide(Slot& slot) {
  const std::span<const double> tdoas(slot.tdoa_s.data(), static_cast<std::size_t>(pair_count_));
  if (!consistent(tdoas)) {
    slot = Slot{};
    return;
  }
  if (highest_elevation_deg(tdoas) > settings_.max_elevation_deg) {
    slot.state = State::sky;  // stays put, but may be a hovering drone: followed, never nulled
    return;
  }
  if (nulled_count() >= settings_.max_sources) return;  // stays tentative until a null frees
  make_signature(slot);
}

void StaticSourceNull::make_signature(Slot& slot) {
  const auto free = std::find(signature_used_.begin(), signature_used_.end(), false);
  if (free == signature_used_.end()) return;
  slot.signature = static_cast<int>(free - signature_used_.begin());
  *free = true;
  slot.state = State::nulled;
  // W_k ~ e^{-j w_k tau} for a source at lag tau: the model is its conjugate, so that
  // Re(W_k model_k) = 1 on a bin the source owns.
  std::vector<std::complex<double>>& signature =
      signatures_[static_cast<std::size_t>(slot.signature)];
  std::size_t index = 0;
  for (int p = 0; p < pair_count_; ++p) {
    const double tau = slot.tdoa_s[static_cast<std::size_t>(p)];
    for (const BandRun& run : band_)
      for (int k = run.first_bin; k <= run.last_bin; ++k)
        signature[index++] = std::polar(1.0, k * bin_omega_ * tau);
  }
  std::copy(signature.begin(), signature.end(),
            models_[static_cast<std::size_t>(slot.signature)].begin());
  std::copy(signature.begin(), signature.end(),
            averages_[static_cast<std::size_t>(slot.signature)].begin());
}

void StaticSourceNull::adapt(int signature_index, const GccPhat& gcc) {
  // The source's own ground reflection (and anything else that is as static as the source)
  // bends each bin's cross-spectrum phase away from the pure delay, by a constant amount: a
  // per-bin average over ~learn_s follows it. A bin that is not steadily the source's (a
  // drone's harmonic passing through, noise) averages out and keeps the delay model.
  const double rate = std::min(1.0, settings_.hop_s / settings_.learn_s);
  std::vector<std::complex<double>>& signature =
      signatures_[static_cast<std::size_t>(signature_index)];
  std::vector<std::complex<double>>& average = averages_[static_cast<std::size_t>(signature_index)];
  const std::vector<std::complex<double>>& model =
      models_[static_cast<std::size_t>(signature_index)];
  for (int p = 0; p < pair_count_; ++p) {
    const std::span<const std::complex<double>> phasor = gcc.phasors(p);
    const std::size_t offset = static_cast<std::size_t>(p) * static_cast<std::size_t>(band_bins_);
    for (int k = 0; k < band_bins_; ++k) {
      const std::size_t index = offset + static_cast<std::size_t>(k);
      std::complex<double>& mean = average[index];
      mean += rate * (std::conj(phasor[static_cast<std::size_t>(k)]) - mean);
      const double size = std::abs(mean);
      const std::complex<double> steady = size > 0.0 ? mean / size : model[index];
      // A reflection half as strong as the direct sound bends a pair's phase by at most
      // 60 deg: a steadier phase further off is another static source's (a hovering drone's
      // harmonic in this bin), not this one's.
      const bool own = size >= kSteadyBin && (steady * std::conj(model[index])).real() >= kMaxBend;
      signature[index] = own ? steady : model[index];
    }
  }
}

double StaticSourceNull::highest_elevation_deg(std::span<const double> tdoas_s) const {
  if (geometry_rank_ < 2) return 90.0;
  Eigen::Vector3d projection = Eigen::Vector3d::Zero();
  for (int p = 0; p < pair_count_; ++p)
    projection +=
        tdoas_s[static_cast<std::size_t>(p)] * pair_baselines_m_[static_cast<std::size_t>(p)];
  Eigen::Vector3d direction = -settings_.speed_of_sound_mps * normal_inverse_ * projection;
  if (geometry_rank_ == 2) {
    // Unresolved along the plane's normal: the two mirror images; the higher one counts.
    const double along = std::sqrt(std::max(0.0, 1.0 - direction.squaredNorm()));
    const Eigen::Vector3d up = direction + along * plane_normal_;
    const Eigen::Vector3d down = direction - along * plane_normal_;
    direction = up.z() >= down.z() ? up : down;
  }
  if (!(direction.norm() > 0.0)) return 90.0;
  return std::asin(std::clamp(direction.z() / direction.norm(), -1.0, 1.0)) * 180.0 /
         std::numbers::pi;
}

}  // namespace dronetrack::doa
