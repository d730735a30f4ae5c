#pragma once
// A source measured on its own harmonic comb's lines (the node's own-comb re-measure) still
// carries, in each line's bins, whatever else sounds there: a car's tyres, an aircraft's or a
// generator's broadband. Their cross-power is smooth across frequency (a plane wave's
// X_i X_j* = |X|^2 exp(-j w tau): a phase that turns by w tau, a few hundredths of a radian per
// bin, and a level that changes slowly), so the bins beside a line, off every comb line, say
// what it is at the line. Subtracting it from the line's cross-power before the phase is taken
// removes the interferer's mean pull on the line's phase (the bias of a drone's DOA towards a
// louder broadband source), and leaves the line's own phase: the source's own broadband beside
// its lines is in phase with them.
#include <cstdint>
#include <span>

#include "doa/gcc_phat.hpp"

namespace dronetrack::doa {

// Bins on each side of a line bin that make its neighbourhood: at the largest lag of a 0.67 m
// pair (~2 ms) the phase turns by ~0.07 rad a bin at 5.9 Hz a bin, so 0.7 rad at the outermost;
// each mirrored pair's mean keeps the phase at the line (cos 0.7 = 0.76 of its level). Each
// neighbour's own fluctuation goes into the line's phase: with n neighbours the subtraction
// adds 1/n of the interferer's variance at the line, so as many as the phase turn allows.
inline constexpr int kLineNeighbourBins = 10;
// The nearest neighbours taken: the line's own bins are the peak +-1 (HarmonicCombDetector).
inline constexpr int kLineNeighbourFirst = 2;

// For every pair and every bin of `gcc`'s band that is kept and on a line (`on_line`, indexed by
// FFT bin minus `first_fft_bin`), replaces the phasor's direction by that of the bin's
// cross-power (from `units` and whiten()'s levels) minus the mean cross-power of its mirrored
// neighbour bins (kLineNeighbourFirst..kLineNeighbourBins away on both sides, in the same band
// run, both off every line and neither a tonal spike: above twice the neighbourhood's median
// level; another source's tonal line is not smooth and says nothing about the line bin). The
// phasor's magnitude (its weight) is kept. Returns how many bins were corrected. No allocation.
int subtract_neighbour_cross_power(GccPhat& gcc, const GccPhat::UnitsView& units,
                                   std::span<const std::uint8_t> on_line, int first_fft_bin);

}  // namespace dronetrack::doa
