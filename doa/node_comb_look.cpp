// The comb look (doa.comb_look, stage 7 in docs/doa.md): one more look, after the free SRP
// search stopped under its floor, on the kept bins of the harmonic comb their power shows.
#include <algorithm>
#include <utility>

#include "doa/node_pipeline_impl.hpp"

namespace dronetrack::doa {

// A rotor puts its power into a few dozen line bins. The free look sums the steered cross-power
// over every kept bin, so a comb whose lines stand far over their noise still peaks under the
// floor set for the whole band: its lines are a small share of the bins, the rest is noise that
// only widens the spread. After the search stops there, one more look on the lines alone: the
// comb the kept bins' power shows (HarmonicCombDetector on the mics' summed |X|^2), its line bins
// kept, the rest dropped. The lines are chosen by power, which says nothing about the phases the
// look sums, so noise on them correlates as on any other bins of that count, and a frame without
// a comb gets no look. The comb is marked when the search stops (mark_comb_look_lines: the bins
// no source owns then, their power only); the look is made after the static look.
void NodePipeline::Impl::mark_comb_look_lines() {
  HarmonicComb comb;
  if (kept_bins_comb(comb) < node_detail::kMinOwnCombLines) return;
  const std::span<const std::uint8_t> kept = std::as_const(gcc).bin_keep();
  std::size_t index = 0;
  for (const BandRun& run : gcc.band())
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index)
      comb_look_keep[index] =
          kept[index] != 0 && comb_lines[static_cast<std::size_t>(k - comb_first_bin)] != 0;
  comb_look_lines = count_lines(comb_look_keep);
}

// The comb the kept bins' power shows (the detector on the mics' summed |X|^2; the bins other
// sources own count as silent), its lines marked in comb_lines; returns how many lines.
int NodePipeline::Impl::kept_bins_comb(HarmonicComb& comb) {
  const auto bins = static_cast<std::size_t>(gcc.band_bin_count());
  const std::span<const double> powers = gcc.band_powers();
  const std::span<const std::uint8_t> kept = std::as_const(gcc).bin_keep();
  std::fill(comb_power.begin(), comb_power.end(), 0.0);
  std::size_t index = 0;
  for (const BandRun& run : gcc.band()) {
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      if (kept[index] == 0) continue;
      double power = 0.0;
      for (int c = 0; c < gcc.unit_channels(); ++c)
        power += powers[static_cast<std::size_t>(c) * bins + index];
      comb_power[static_cast<std::size_t>(k - comb_first_bin)] = power;
    }
  }
  comb = own_comb->detect(comb_power);
  return own_comb->mark_lines(comb, comb_lines);
}

// Runs of kept bins in band order: a line is +-1 bin of a peak, and two lines of a comb are at
// least its lowest spacing (40 Hz, 6 bins) apart.
int NodePipeline::Impl::count_lines(std::span<const std::uint8_t> keep) const {
  int lines = 0;
  std::size_t index = 0;
  for (const BandRun& run : gcc.band()) {
    bool on_line = false;
    for (int k = run.first_bin; k <= run.last_bin; ++k, ++index) {
      lines += keep[index] != 0 && !on_line ? 1 : 0;
      on_line = keep[index] != 0;
    }
  }
  return lines;
}

void NodePipeline::Impl::comb_look(int first_unmasked) {
  // The lines no source owned when the search stopped, minus the bins of the sources added
  // since (the static look's).
  gcc.cross_power(gcc.units(), comb_look_keep);
  drop_candidates(first_unmasked, candidate_count);
  const std::span<const std::uint8_t> keep = std::as_const(gcc).bin_keep();
  const int lines = first_unmasked < candidate_count ? count_lines(keep) : comb_look_lines;
  if (lines < node_detail::kMinOwnCombLines) return;  // its lines are the others'
  gcc.correlate(false, false);
  srp->begin_frame(gcc);
  ++diagnostics.comb_looks;
  // A line's bins (its window's main lobe) hold one phasor per pair, not one per bin: the look
  // averages `lines` independent values per pair, and noise-only lines reach the floor as
  // rarely as the whole band's bins reach theirs (srp_noise_sigma, node_setup.cpp).
  const double floor = params.srp_min_power_sigmas / std::sqrt(2.0 * lines * solver.pair_count());
  trace_comb_look(static_cast<int>(std::count(keep.begin(), keep.end(), std::uint8_t{1})), floor);
  SrpPeak peak;
  if (!srp->strongest(peak, floor) || !solve_look(peak, LookKind::comb)) return;
  Candidate& candidate = candidates[static_cast<std::size_t>(candidate_count)];
  const std::span<const PairTdoa> candidate_tdoas(candidate.tdoas.data(), tdoas.size());
  // On its lines alone a source correlates as fringes one carrier period apart: a look on a
  // found source's fringe is that source again, and its bins would be taken from it.
  if (below_horizon(candidate.solution) ||
      fringe_of_found(candidate_tdoas, candidate.solution.direction_site))
    return;
  accept_candidate();
  ++diagnostics.comb_look_sources;
}

}  // namespace dronetrack::doa
