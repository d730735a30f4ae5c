#pragma once
// Finds a harmonic comb in a power spectrum: the evenly spaced lines of a rotor's blade-passage
// harmonics (a drone: fundamental 80-400 Hz, many harmonics drifting together), and how much of
// the power they carry. A generator's mains-locked comb (50/60 Hz), a car's broadband and a
// single whine are told apart by the spacing found, the comb's strength and the broadband share.
//
// Method: each bin's salience is its log power over the local median-free envelope (a moving
// mean of the log power, so one loud line does not lift its neighbours' floor), clipped at 0:
// only lines stand out. The comb spacing is the lag of the salience's normalised autocorrelation
// peak within the search range; a comb at spacing L also correlates at 2L, 3L but anti-correlates
// at L/2, so the smallest lag within 15 % of the best is taken. The autocorrelation does not move
// when the harmonics drift together (a rotor speeding up moves line h by h times as much, the
// spacing by a fraction of a bin), so a mean of several frames' autocorrelations (CombHistory)
// finds a comb too weak for one frame. Harmonics are counted on the last spectrum analysed.
// Preallocated in the constructor; nothing is allocated per frame.
#include <cstdint>
#include <span>
#include <vector>

namespace dronetrack::doa {

struct HarmonicCombSettings {
  double min_fundamental_hz = 40.0;      // search range of the comb spacing
  double max_fundamental_hz = 500.0;     //
  double envelope_half_width_hz = 90.0;  // local envelope: mean log power over +- this
  double line_salience_db = 6.0;         // a harmonic stands this far above its envelope
  double min_strength = 0.15;            // autocorrelation at the spacing to call it a comb
  int min_harmonics = 3;                 // lines on the comb to call it a comb
};

struct HarmonicComb {
  bool found = false;
  double fundamental_hz = 0.0;  // comb spacing (0 when not found)
  double strength = 0.0;        // normalised salience autocorrelation at the spacing, 0..1
  int harmonic_count = 0;       // lines on the comb standing line_salience_db over the envelope
  // Share of the analysed power within +-1.5 bins of the comb's lines (0 when not found); the
  // rest is broadband (or lines off the comb).
  double harmonic_share = 0.0;
};

class HarmonicCombDetector {
 public:
  // The spectra analysed are bins [first_bin, first_bin + bin_count) at bin_hz (bin k is at
  // k * bin_hz). Throws std::invalid_argument naming a bad setting.
  HarmonicCombDetector(int first_bin, int bin_count, double bin_hz,
                       const HarmonicCombSettings& settings = {});

  // One spectrum: power[i] is the power of bin first_bin + i. Bins with power <= 0 (another
  // source's, or outside the bands) carry no salience and no power. Fills `autocorrelation`
  // (lag_count() values, lags first_lag() ...) and keeps the salience for find().
  void autocorrelate(std::span<const double> power, std::span<double> autocorrelation);
  // The comb in an autocorrelation (this frame's, or a mean over frames); its lines are counted
  // on the spectrum of the last autocorrelate().
  HarmonicComb find(std::span<const double> autocorrelation) const;
  // Both, on one spectrum.
  HarmonicComb analyse(std::span<const double> power);
  // The comb of one spectrum if one is found, else an empty HarmonicComb (a rejected comb's
  // strength and lines are not reported): what analyse() finds, for less when there is none.
  HarmonicComb detect(std::span<const double> power);
  // The bins within one bin of each line of `comb` (found on the last spectrum analysed) set to
  // 1 in on_line (bin_count() values, index i = bin first_bin + i), the rest 0; returns the
  // number of lines.
  int mark_lines(const HarmonicComb& comb, std::span<std::uint8_t> on_line) const;

  int lag_count() const { return last_lag_ - first_lag_ + 1; }
  int first_lag() const { return first_lag_; }
  int bin_count() const { return bin_count_; }
  double bin_hz() const { return bin_hz_; }
  const HarmonicCombSettings& settings() const { return settings_; }

 private:
  template <typename OnLine>
  int walk_lines(double fundamental_hz, OnLine&& on_line) const;
  // The spectrum's salience (power_, salience_ less its mean, valid_); returns how many bins
  // stand line_salience_db over their envelope.
  int measure_salience(std::span<const double> power);
  void autocorrelate_salience(std::span<double> autocorrelation) const;

  HarmonicCombSettings settings_;
  int first_bin_;
  int bin_count_;
  double bin_hz_;
  int first_lag_ = 0;  // one below the search range (the refinement's left neighbour)
  int last_lag_ = 0;   // one above
  int envelope_half_width_bins_;
  bool valid_ = false;  // the last spectrum had enough bins with power
  double salience_mean_ = 0.0;
  double total_power_ = 0.0;
  double energy_ = 0.0;  // of the mean-free salience
  std::vector<double> power_;
  std::vector<double> log_power_;
  std::vector<double> prefix_;  // prefix sums of log power over valid bins (envelope)
  std::vector<int> prefix_count_;
  std::vector<float> salience_;  // float: four lanes per SIMD register in the autocorrelation
  std::vector<double> autocorrelation_;  // analyse()'s
};

}  // namespace dronetrack::doa
