#pragma once
// Deterministic random streams. A scene must render bit-identically from its seed on every
// machine and whichever array is rendered first, so every component (source i, mic j of array k,
// noise type) draws from its own stream derived from (seed, stream id), and the generators are
// written out here rather than taken from <random>, whose distributions differ between
// standard libraries.
#include <cmath>
#include <cstdint>
#include <numbers>

namespace dronetrack::sim {

// SplitMix64: used to seed and as a hash of (seed, stream).
inline std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Stream ids are built from small integers: stream_id(kind, a, b).
constexpr std::uint64_t stream_id(std::uint64_t kind, std::uint64_t a = 0, std::uint64_t b = 0) {
  return (kind << 48) ^ (a << 24) ^ b;
}

// xoshiro256+ (Blackman and Vigna): fast, good enough for noise.
class Random {
 public:
  Random(std::uint64_t seed, std::uint64_t stream) {
    std::uint64_t state = seed * 0x9e3779b97f4a7c15ULL ^ (stream + 0x632be59bd9b4e019ULL);
    for (auto& word : s_) word = splitmix64(state);
  }
  std::uint64_t next() {
    const std::uint64_t result = s_[0] + s_[3];
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = (s_[3] << 45) | (s_[3] >> 19);
    return result;
  }
  // Uniform in [0, 1).
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double low, double high) { return low + (high - low) * uniform(); }
  // Exact standard normal (Box-Muller); for parameters and spectra, not per audio sample.
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
  // Unit-variance, near-normal (sum of four 16-bit uniforms, Irwin-Hall): one generator call per
  // sample. Noise at tens of millions of samples per scene cannot afford a logarithm each.
  float fast_normal() {
    const std::uint64_t bits = next();
    const auto sum = static_cast<float>((bits & 0xffff) + ((bits >> 16) & 0xffff) +
                                        ((bits >> 32) & 0xffff) + (bits >> 48));
    // Mean 4 * 32767.5, variance 4 * (65536^2 - 1) / 12.
    constexpr float kMean = 131070.0f;
    constexpr float kInverseStd = 1.0f / 37837.23f;
    return (sum - kMean) * kInverseStd;
  }

 private:
  std::uint64_t s_[4];
};

}  // namespace dronetrack::sim
