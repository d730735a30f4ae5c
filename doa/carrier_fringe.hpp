#pragma once
// A source heard only on its rotor's lines correlates, on every pair, as fringes one carrier
// period apart under an envelope as wide as the inverse of its lines' span, the neighbouring
// fringes nearly as high as the peak (docs/doa.md, "D2 at N1"). A direction on such a fringe
// steers onto the source's lines near the carrier in phase and onto the others out of phase, so
// its steered spectrum shows a few of the source's own lines (the same spacing) or no comb at
// all. These judge whether a second direction found beside a comb source is that source again.
#include <cstdint>
#include <span>

#include "doa/harmonic_comb.hpp"

namespace dronetrack::doa {

// The comb's carrier: the power-weighted mean frequency of its lines. power[i] and on_line[i]
// are bin first_bin + i at bin_hz. 0 when no line carries power.
double comb_carrier_hz(std::span<const double> power, std::span<const std::uint8_t> on_line,
                       int first_bin, double bin_hz);

// Whether the lags of `lags_other_s` lie within one carrier fringe of `lags_source_s`: on every
// pair the difference is nearer to zero or one carrier period than to two (|dt| <= 1.5 / f).
// Pairs whose lag is not finite in either are left out; false when none is left.
bool within_one_carrier_fringe(std::span<const double> lags_source_s,
                               std::span<const double> lags_other_s, double carrier_hz);

// Whether a comb measured at another direction is the source's own seen through a fringe: it
// has fewer than min_lines lines (no comb of its own), or its spacing is the source's within
// spacing_tolerance_hz (the comb spacing's resolution: the same lines in the same frame).
bool comb_is_the_sources(const HarmonicComb& source, const HarmonicComb& other, int min_lines,
                         double spacing_tolerance_hz);

}  // namespace dronetrack::doa
