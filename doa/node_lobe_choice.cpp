// NodePipeline's choice of a free look's carrier lobe (docs/doa.md, stage 7, "A free look's
// lobe"). A source left with only its rotor's lines correlates as fringes one carrier period
// apart, the neighbours nearly as high as the peak, and its ground echo can lift one above it.
// The true lags bring every line into phase on every pair; a neighbouring fringe only the lines
// near the carrier. So the look's lags and those one carrier period away at each mic are judged
// by how well they align the lines of the harmonic comb the kept bins hold, each line bin
// counted the same (the SRP's sum over every kept bin also counts the noise and the other
// sources' leftovers between the lines, which the echo and the near carrier lines can tip
// towards a fringe). The lines are found in the kept bins' power, not in the look's steered
// spectrum: on a fringe that shows the lines near the carrier only, most often too few to call
// a comb (carrier_fringe.hpp; docs/doa.md, session 18).
#include <algorithm>
#include <cmath>

#include "doa/node_pipeline_impl.hpp"

namespace dronetrack::doa {

namespace {
// A neighbouring lobe replaces the look only when it aligns the lines better by this much (mean
// agreement over the line bins, 1 = all in phase on every pair): the mean over ~50 line bins of
// noise-only agreements (sd ~0.3 each over six pairs) has sd ~0.05, so this is two of them
// (a comb of 10-15 lines marks 30-45 bins).
constexpr double kLobeMargin = 0.1;
// Lobes within this of the look are the look again (the refinement climbed back).
constexpr double kSameLobeCosine = 0.99939;  // cos(2 deg)
}  // namespace

// How many lines the comb of the steered spectrum at `lags` on the kept bins shows
// (keep_own_comb's comb).
int NodePipeline::Impl::steered_lines(std::span<const PairTdoa> lags, HarmonicComb& comb) {
  int pairs = 0;
  comb = steered_comb(lags, gcc.units(), gcc.bin_keep(), pairs);
  return pairs == 0 ? 0 : own_comb->mark_lines(comb, comb_lines);
}

// Over the line bins, the pair's agreement with its lag, cos(phase_ij - w tau_ij) as steer()
// sums it (look), and with the lag one carrier period later and earlier. The steered phasor
// z = a b* e^{j w tau} of each line bin is made once: one period P later turns it by e^{j w P}.
NodePipeline::Impl::PairLineSums NodePipeline::Impl::pair_line_sums(int pair, double tdoa_s) const {
  const GccPhat::UnitsView units = gcc.units();
  const MicPairSpec& spec = gcc.pair_spec(pair);
  const std::span<const double> ri = units.real_row(spec.mic_i);
  const std::span<const double> ii = units.imag_row(spec.mic_i);
  const std::span<const double> rj = units.real_row(spec.mic_j);
  const std::span<const double> ij = units.imag_row(spec.mic_j);
  const double turn = gcc.bin_omega_rad_per_s() * tdoa_s;
  PairLineSums sums;
  for (int n = 0; n < lobe_line_count; ++n) {
    const LineBin& line = lobe_lines[static_cast<std::size_t>(n)];
    const std::size_t b = line.band_index;
    const double re = ri[b] * rj[b] + ii[b] * ij[b];
    const double im = ii[b] * rj[b] - ri[b] * ij[b];
    const double phase = turn * line.fft_bin;
    const double cosine = std::cos(phase);
    const double sine = std::sin(phase);
    const double zr = re * cosine - im * sine;
    const double zi = re * sine + im * cosine;
    sums.look += zr;
    sums.later += zr * line.period_re - zi * line.period_im;
    sums.earlier += zr * line.period_re + zi * line.period_im;
  }
  return sums;
}

// Every pair's line sums (pair_line_sums) at the lags into line_sums, 0 for a pair without a
// lag; returns the look's mean agreement over the pairs with a lag and the line bins: 1 when
// every line is in phase at the lags.
double NodePipeline::Impl::all_line_sums(std::span<const PairTdoa> lags) {
  double sum = 0.0;
  int pairs = 0;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const PairTdoa& tdoa = lags[static_cast<std::size_t>(p)];
    PairLineSums& pair = line_sums[static_cast<std::size_t>(p)];
    pair = tdoa.variance_s2 > 0.0 ? pair_line_sums(p, tdoa.tdoa_s) : PairLineSums{};
    if (!(tdoa.variance_s2 > 0.0)) continue;
    ++pairs;
    sum += pair.look;
  }
  line_sum_pairs = pairs;
  return pairs == 0 || lobe_line_count == 0 ? 0.0
                                            : sum / (static_cast<double>(pairs) * lobe_line_count);
}

// A fringe reads one mic's arrival a carrier period early or late: every pair holding that mic
// moves by one period, the others stay. Lobe `lobe` is mic lobe / 2, early (even) or late (odd).
void NodePipeline::Impl::shifted_lags(std::span<const PairTdoa> look_tdoas, int lobe,
                                      double period_s) {
  const int mic = lobe / 2;
  const double sign = lobe % 2 == 0 ? -1.0 : 1.0;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const MicPairSpec& spec = gcc.pair_spec(p);
    const auto pair = static_cast<std::size_t>(p);
    lobe_tdoas[pair] = look_tdoas[pair];
    if (spec.mic_i == mic) lobe_tdoas[pair].tdoa_s += sign * period_s;
    if (spec.mic_j == mic) lobe_tdoas[pair].tdoa_s -= sign * period_s;
  }
}

// Each moved pair's correlation maximum nearest its shifted lag.
void NodePipeline::Impl::refine_lobe(std::span<const PairTdoa> look_tdoas) {
  for (std::size_t p = 0; p < static_cast<std::size_t>(gcc.pair_count()); ++p) {
    if (lobe_tdoas[p].tdoa_s == look_tdoas[p].tdoa_s || !(look_tdoas[p].variance_s2 > 0.0))
      continue;
    GccPeak peak;
    lobe_tdoas[p] = gcc.refine(static_cast<int>(p), lobe_tdoas[p].tdoa_s, peak) && peak.value > 0.0
                        ? PairTdoa{peak.lag_s, gcc.tdoa_variance_for_peak(peak.value), peak.value,
                                   peak.coherence}
                        : PairTdoa{};
  }
}

// The lines judged (lobe_lines): the comb of the kept bins' power (summed over the mics; the
// sources found so far own the other bins), found and marked by the comb detector
// keep_own_comb uses. Returns its carrier, 0 when it shows fewer than kMinOwnCombLines lines.
double NodePipeline::Impl::mark_kept_comb(HarmonicComb& comb) {
  lobe_line_count = 0;
  if (kept_bins_comb(comb) < node_detail::kMinOwnCombLines) return 0.0;
  const std::span<const std::uint8_t> keep = gcc.bin_keep();
  std::size_t index = 0;
  for (const BandRun& run : gcc.band())
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index)
      if (keep[index] != 0 && comb_lines[static_cast<std::size_t>(k - comb_first_bin)] != 0)
        lobe_lines[static_cast<std::size_t>(lobe_line_count++)] = {index, k};
  return comb_carrier_hz(comb_power, comb_lines, comb_first_bin, own_comb->bin_hz());
}

// The look's alignment, and into lobe_order (lobes_screened of them) the lobes one carrier
// period away at each mic that align the lines better at the shifted lags: every lobe's sum is
// the look's with its moved pairs' sums turned by one period (no sin/cos per lobe).
double NodePipeline::Impl::screen_lobes(std::span<const PairTdoa> look_tdoas, double carrier_hz) {
  const double omega = gcc.bin_omega_rad_per_s();
  const double period_s = 1.0 / carrier_hz;
  for (int n = 0; n < lobe_line_count; ++n) {
    LineBin& line = lobe_lines[static_cast<std::size_t>(n)];
    line.period_re = std::cos(omega * period_s * line.fft_bin);
    line.period_im = std::sin(omega * period_s * line.fft_bin);
  }
  const double look_alignment = all_line_sums(look_tdoas);
  lobes_screened = 0;
  if (line_sum_pairs == 0) return 0.0;
  const double scale = 1.0 / (static_cast<double>(line_sum_pairs) * lobe_line_count);
  // Lobe l reads mic l / 2 one period early (l even) or late (shifted_lags()).
  for (int l = 0; l < 2 * gcc.unit_channels(); ++l) {
    const int mic = l / 2;
    const bool late = l % 2 == 1;
    double sum = 0.0;
    for (int p = 0; p < gcc.pair_count(); ++p) {
      const MicPairSpec& spec = gcc.pair_spec(p);
      const PairLineSums& pair = line_sums[static_cast<std::size_t>(p)];
      // The pair's lag moves with mic i's reading and against mic j's.
      if (spec.mic_i == mic)
        sum += late ? pair.later : pair.earlier;
      else if (spec.mic_j == mic)
        sum += late ? pair.earlier : pair.later;
      else
        sum += pair.look;
    }
    if (sum * scale > look_alignment)
      lobe_order[static_cast<std::size_t>(lobes_screened++)] = {sum * scale, l};
  }
  return look_alignment;
}

bool NodePipeline::Impl::choose_lobe(std::span<PairTdoa> look_tdoas, DoaSolution& solution) {
  if (!own_comb || lobe_lines.empty() || !solution.accepted) return false;
  HarmonicComb kept_comb;
  const double carrier_hz = mark_kept_comb(kept_comb);
  if (!(carrier_hz > 0.0)) return false;
  const auto pairs = static_cast<std::size_t>(gcc.pair_count());
  const std::span<const PairTdoa> lobe(lobe_tdoas.data(), pairs);
  // Judged first at the look's lags moved by exactly one period (no grid climb, no solve): only
  // a lobe that aligns the lines better there is measured (each moved pair's correlation
  // maximum nearest the shifted lag) and solved, best first, and judged again on its own lags.
  const double look_alignment = screen_lobes(look_tdoas, carrier_hz);
  const int screened = lobes_screened;
  if (screened == 0) return false;
  // A look that steers out a comb of its own spacing other than the kept bins' is on another
  // source than the one whose lines would be judged (two drones' lines sharing the kept bins
  // where their rays cross): it stays.
  HarmonicComb look_comb;
  if (steered_lines(look_tdoas, look_comb) >= node_detail::kMinOwnCombLines &&
      std::abs(look_comb.fundamental_hz - kept_comb.fundamental_hz) > 0.5 * own_comb->bin_hz())
    return false;
  std::sort(lobe_order.begin(), lobe_order.begin() + screened,
            [](const auto& a, const auto& b) { return a.first > b.first; });
  for (int rank = 0; rank < screened; ++rank) {
    const int l = lobe_order[static_cast<std::size_t>(rank)].second;
    shifted_lags(look_tdoas, l, 1.0 / carrier_hz);
    refine_lobe(look_tdoas);
    const DoaSolution lobe_solution = solver.solve(lobe);
    // A lobe below the horizon or on a source already found would hand the look's lines to
    // the horizon mask's drop or to the duplicate's subtraction: the look is kept instead.
    if (!lobe_solution.accepted ||
        lobe_solution.direction_site.dot(solution.direction_site) >= kSameLobeCosine ||
        (solver.rank() >= 3 && lobe_solution.direction_site.z() < min_elevation_sine) ||
        already_found(lobe_solution.direction_site))
      continue;
    // Its lines agree with a source as its own bins do (SourceBinMask's test).
    const double alignment = all_line_sums(lobe);
    if (alignment < node_detail::kOwnBinAgreement || alignment <= look_alignment + kLobeMargin)
      continue;
    std::copy(lobe.begin(), lobe.end(), look_tdoas.begin());
    solution = lobe_solution;
    ++diagnostics.free_look_lobes_moved;
    return true;
  }
  return false;
}

}  // namespace dronetrack::doa
