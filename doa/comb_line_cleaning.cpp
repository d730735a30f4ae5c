#include "doa/comb_line_cleaning.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstddef>

namespace dronetrack::doa {

namespace {

// A bin's level above this many times the neighbourhood's median is a tonal line.
constexpr double kTonalSpike = 2.0;
// Below this share of the line's own level the corrected cross-power is left as it was: the
// line is then as good as all interferer and the difference only noise.
constexpr double kMinResidualShare = 1e-3;

}  // namespace

int subtract_neighbour_cross_power(GccPhat& gcc, const GccPhat::UnitsView& units,
                                   std::span<const std::uint8_t> on_line, int first_fft_bin) {
  const std::span<const std::uint8_t> keep = std::as_const(gcc).bin_keep();
  const std::span<const double> levels = gcc.band_levels();
  const auto bins = static_cast<std::size_t>(gcc.band_bin_count());
  const auto line_at = [&](int fft_bin) {
    const auto bin = static_cast<std::size_t>(fft_bin - first_fft_bin);
    return bin < on_line.size() && on_line[bin] != 0;
  };
  constexpr int kSide = kLineNeighbourBins - kLineNeighbourFirst + 1;
  int corrected = 0;
  for (int p = 0; p < gcc.pair_count(); ++p) {
    const MicPairSpec& spec = gcc.pair_spec(p);
    const std::span<const double> ri = units.real_row(spec.mic_i);
    const std::span<const double> ii = units.imag_row(spec.mic_i);
    const std::span<const double> rj = units.real_row(spec.mic_j);
    const std::span<const double> ij = units.imag_row(spec.mic_j);
    const double* level_i = levels.data() + static_cast<std::size_t>(spec.mic_i) * bins;
    const double* level_j = levels.data() + static_cast<std::size_t>(spec.mic_j) * bins;
    // G_ij = |X_i| |X_j| u_i u_j* at band index b.
    const auto cross = [&](std::size_t b) {
      return level_i[b] * level_j[b] *
             std::complex<double>(ri[b] * rj[b] + ii[b] * ij[b], ii[b] * rj[b] - ri[b] * ij[b]);
    };
    std::size_t run_start = 0;
    for (const BandRun& run : gcc.band()) {
      const int run_bins = run.last_bin - run.first_bin + 1;
      for (int offset = 0; offset < run_bins; ++offset) {
        const std::size_t index = run_start + static_cast<std::size_t>(offset);
        if (keep[index] == 0 || !line_at(run.first_bin + offset)) continue;
        // The mirrored pairs inside the run with both bins off the lines.
        std::array<int, kSide> distances{};
        std::array<double, 2 * kSide> neighbour_levels{};
        int usable = 0;
        for (int d = kLineNeighbourFirst; d <= kLineNeighbourBins; ++d) {
          if (offset - d < 0 || offset + d >= run_bins) break;
          if (line_at(run.first_bin + offset - d) || line_at(run.first_bin + offset + d)) continue;
          const std::size_t below = index - static_cast<std::size_t>(d);
          const std::size_t above = index + static_cast<std::size_t>(d);
          neighbour_levels[static_cast<std::size_t>(2 * usable)] = level_i[below] * level_j[below];
          neighbour_levels[static_cast<std::size_t>(2 * usable + 1)] =
              level_i[above] * level_j[above];
          distances[static_cast<std::size_t>(usable)] = d;
          ++usable;
        }
        if (usable == 0) continue;
        std::array<double, 2 * kSide> sorted = neighbour_levels;
        const auto middle = sorted.begin() + usable;
        std::nth_element(sorted.begin(), middle, sorted.begin() + 2 * usable);
        const double spike = kTonalSpike * *middle;
        std::complex<double> sum{};
        int taken = 0;
        for (int n = 0; n < usable; ++n) {
          if (neighbour_levels[static_cast<std::size_t>(2 * n)] > spike ||
              neighbour_levels[static_cast<std::size_t>(2 * n + 1)] > spike)
            continue;
          const auto d = static_cast<std::size_t>(distances[static_cast<std::size_t>(n)]);
          sum += cross(index - d) + cross(index + d);
          taken += 2;
        }
        if (taken == 0) continue;
        const std::complex<double> line = cross(index);
        const std::complex<double> residual = line - sum / static_cast<double>(taken);
        if (std::norm(residual) <= kMinResidualShare * kMinResidualShare * std::norm(line))
          continue;
        gcc.redirect_phasor(p, static_cast<int>(index), residual);
        ++corrected;
      }
      run_start += static_cast<std::size_t>(run_bins);
    }
  }
  return corrected;
}

}  // namespace dronetrack::doa
