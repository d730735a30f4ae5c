// NodePipeline's choice of a free look's carrier lobe (docs/doa.md, stage 7, "A free look's
// lobe"). A source left with only its rotor's lines correlates as fringes one carrier period
// apart, the neighbours nearly as high as the peak, and its ground echo can lift one above it.
// The true lags bring every line into phase on every pair; a neighbouring fringe only the lines
// near the carrier. So the look's lags and those one carrier period away at each mic are judged
// by how well they align the lines the kept bins hold, each line bin counted the same (the SRP's
// sum over every kept bin also counts the noise and the other sources' leftovers between the
// lines, which the echo and the near carrier lines can tip towards a fringe).
#include <algorithm>
#include <cmath>

#include "doa/node_pipeline_impl.hpp"

namespace dronetrack::doa {

namespace {
// A neighbouring lobe replaces the look only when it aligns the lines better by this much (mean
// agreement over the line bins, 1 = all in phase on every pair): the mean over ~50 line bins of
// noise-only agreements (sd ~0.3 each over six pairs) has sd ~0.05, so this is two of them.
constexpr double kLobeMargin = 0.1;
// Lobes within this of the look are the look again (the refinement climbed back).
constexpr double kSameLobeCosine = 0.99939;  // cos(2 deg)
// A line stands this far over the frame's local level (HarmonicCombSettings' line salience,
// 6 dB, as a natural log of power), the local level being the mean log power over +-90 Hz.
constexpr double kLineSalience = 1.3815510557964274;  // ln(10^0.6)
constexpr double kEnvelopeHalfWidthHz = 90.0;
}  // namespace

// A line is judged on the frame's whole band (the mics' mean power before any bin was dropped),
// so it stands over the broadband around it whatever the masks dropped; it counts when its bin
// is kept (the sources found so far own the others).
double NodePipeline::Impl::mark_kept_lines() {
  const std::span<const std::uint8_t> keep = gcc.bin_keep();
  const auto bins = static_cast<std::size_t>(gcc.band_bin_count());
  const std::span<const double> powers = gcc.band_powers();
  std::vector<double>& level = lobe_log_power;  // band bin b's log power at b
  for (std::size_t b = 0; b < bins; ++b) {
    double power = 0.0;
    for (int c = 0; c < gcc.unit_channels(); ++c)
      power += powers[static_cast<std::size_t>(c) * bins + b];
    level[b] = std::log(std::max(power, 1e-300));
  }
  const double bin_hz = sample_rate_hz / fft.fft_size();
  const auto half =
      static_cast<std::size_t>(std::max(2.0, std::round(kEnvelopeHalfWidthHz / bin_hz)));
  std::fill(lobe_line_bins.begin(), lobe_line_bins.end(), std::uint8_t{0});
  double window = 0.0;  // sum of level over [low, high)
  std::size_t low = 0;
  std::size_t high = 0;
  int lines = 0;
  int line_bins = 0;
  double frequency_sum_hz = 0.0;
  std::size_t b = 0;
  for (const BandRun& run : gcc.band()) {
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++b) {
      const std::size_t want_high = std::min(bins, b + half + 1);
      const std::size_t want_low = b > half ? b - half : 0;
      while (high < want_high) window += level[high++];
      while (low < want_low) window -= level[low++];
      const double envelope = window / static_cast<double>(high - low);
      const bool peak =
          (b == 0 || level[b] > level[b - 1]) && (b + 1 == bins || level[b] >= level[b + 1]);
      if (!peak || keep[b] == 0 || level[b] - envelope < kLineSalience) continue;
      ++lines;
      for (std::size_t n = b > 0 ? b - 1 : 0; n <= std::min(bins - 1, b + 1); ++n) {
        if (keep[n] == 0 || lobe_line_bins[n] != 0) continue;
        lobe_line_bins[n] = 1;
        ++line_bins;
        frequency_sum_hz += (k + static_cast<int>(n) - static_cast<int>(b)) * bin_hz;
      }
    }
  }
  lobe_line_bin_count = line_bins;
  if (lines < node_detail::kMinOwnCombLines || line_bins == 0) return 0.0;
  return frequency_sum_hz / line_bins;
}

// Mean over the line bins of the mean over the pairs that carry a lag of cos(phase_ij - w tau_ij):
// 1 when every line is in phase at the lags.
double NodePipeline::Impl::line_alignment(std::span<const PairTdoa> lags) {
  std::fill(lobe_power.begin(), lobe_power.end(), 0.0);
  std::fill(lobe_agreement.begin(), lobe_agreement.end(), 0.0);
  const int pairs = steer(lags, gcc.units(), lobe_line_bins, lobe_power, lobe_agreement);
  if (pairs == 0 || lobe_line_bin_count == 0) return 0.0;
  double sum = 0.0;
  for (const double agreement : lobe_agreement) sum += agreement;
  return sum / (static_cast<double>(pairs) * lobe_line_bin_count);
}

bool NodePipeline::Impl::choose_lobe(std::span<PairTdoa> look_tdoas, DoaSolution& solution) {
  if (lobe_line_bins.empty() || !solution.accepted) return false;
  const double carrier_hz = mark_kept_lines();
  if (!(carrier_hz > 0.0)) return false;
  const double period_s = 1.0 / carrier_hz;
  const auto pairs = static_cast<std::size_t>(gcc.pair_count());
  const double look_alignment = line_alignment(look_tdoas);
  double best_alignment = look_alignment + kLobeMargin;
  bool moved = false;
  // A fringe reads one mic's arrival a carrier period early or late: every pair holding that mic
  // moves by one period, the others stay.
  for (int mic = 0; mic < gcc.unit_channels(); ++mic) {
    for (const double sign : {-1.0, 1.0}) {
      bool touched = false;
      for (std::size_t p = 0; p < pairs; ++p) {
        const MicPairSpec& spec = gcc.pair_spec(static_cast<int>(p));
        const double shift =
            spec.mic_i == mic ? sign * period_s : (spec.mic_j == mic ? -sign * period_s : 0.0);
        lobe_tdoas[p] = look_tdoas[p];
        if (shift == 0.0 || !(look_tdoas[p].variance_s2 > 0.0)) continue;
        GccPeak peak;
        touched = true;
        lobe_tdoas[p] =
            gcc.refine(static_cast<int>(p), look_tdoas[p].tdoa_s + shift, peak) && peak.value > 0.0
                ? PairTdoa{peak.lag_s, gcc.tdoa_variance_for_peak(peak.value), peak.value,
                           peak.coherence}
                : PairTdoa{};
      }
      if (!touched) continue;
      const std::span<const PairTdoa> lobe(lobe_tdoas.data(), pairs);
      const DoaSolution lobe_solution = solver.solve(lobe);
      // A lobe below the horizon or on a source already found would hand the look's lines to
      // the horizon mask's drop or to the duplicate's subtraction: the look is kept instead.
      if (!lobe_solution.accepted ||
          lobe_solution.direction_site.dot(solution.direction_site) >= kSameLobeCosine ||
          (solver.rank() >= 3 && lobe_solution.direction_site.z() < min_elevation_sine) ||
          already_found(lobe_solution.direction_site))
        continue;
      // Its own lines agree with a source as its own bins do (SourceBinMask's test): lines of
      // other sources that no lobe aligns do not move the look.
      const double alignment = line_alignment(lobe);
      if (alignment <= best_alignment || alignment < node_detail::kOwnBinAgreement) continue;
      best_alignment = alignment;
      std::copy(lobe.begin(), lobe.end(), best_lobe_tdoas.begin());
      best_lobe_solution = lobe_solution;
      moved = true;
    }
  }
  if (!moved) return false;
  std::copy_n(best_lobe_tdoas.begin(), pairs, look_tdoas.begin());
  solution = best_lobe_solution;
  ++diagnostics.free_look_lobes_moved;
  return true;
}

}  // namespace dronetrack::doa
