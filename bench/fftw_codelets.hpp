#pragma once
// FFTW picks its codelets from the CPU (SSE2 or AVX on Debian's build), not from the target
// Highway is forced to. A bench that forces the DSP kernels to two-lane SSE4 on an AVX machine
// would still time FFTW's four-lane AVX codelets, a CPU no appliance has: the FFT would be
// faster than on an SSE4 box and every ratio to it pessimistic. These force FFTW's side too.
#include <string>

namespace dronetrack::bench {

// Lets FFTW plan with its AVX codelets (what the CPU has, the default) or only with SSE2 ones,
// as on a CPU without AVX. Call it before making plans: FFTW asks at planning time.
void allow_fftw_avx(bool allowed);
// The codelets an r2c plan of `size` points gets now, from FFTW's own plan print:
// "AVX", "SSE2" or "scalar" (proof of the path taken, as the kernels' dispatch counts).
std::string fftw_codelet_set(int size);

}  // namespace dronetrack::bench
