#include "bench/fftw_codelets.hpp"

#include <dlfcn.h>
#include <fftw3.h>

#include <cstdlib>
#include <vector>

namespace {
bool avx_allowed = true;
}  // namespace

// FFTW's solvers ask this (exported, called through the library's PLT) whether the CPU runs
// its AVX codelets; the executable's definition takes the call, so saying no leaves FFTW the
// SSE2 codelets it would use on a CPU without AVX. There is no public planner flag for it
// (FFTW_NO_SIMD drops SSE2 too).
extern "C" int fftw_have_simd_avx(void) {
  using Probe = int (*)(void);
  static const Probe library = reinterpret_cast<Probe>(dlsym(RTLD_NEXT, "fftw_have_simd_avx"));
  return avx_allowed && library != nullptr && library() != 0 ? 1 : 0;
}

namespace dronetrack::bench {

void allow_fftw_avx(bool allowed) { avx_allowed = allowed; }

std::string fftw_codelet_set(int size) {
  std::vector<double> input(static_cast<std::size_t>(size));
  std::vector<fftw_complex> output(static_cast<std::size_t>(size / 2 + 1));
  fftw_plan plan = fftw_plan_dft_r2c_1d(size, input.data(), output.data(), FFTW_ESTIMATE);
  char* printed = fftw_sprint_plan(plan);
  const std::string text = printed != nullptr ? printed : "";
  std::free(printed);
  fftw_destroy_plan(plan);
  if (text.find("avx") != std::string::npos) return "AVX";
  if (text.find("sse2") != std::string::npos) return "SSE2";
  return "scalar";
}

}  // namespace dronetrack::bench
