#pragma once
// Which vector code the DSP kernels run (Google Highway's run-time dispatch): the best target
// the CPU has unless forced, and how many kernel calls each target has served.
#include <cstdint>
#include <string>

namespace dronetrack::doa {

// Forces the kernels onto one Highway target by its name ("AVX3" or "AVX512", "AVX2", "SSE4",
// "NEON", "SVE", "EMU128", ...), or back to the best one with "" or "auto". Throws
// std::invalid_argument when this CPU or build has no such target. Process-wide: call it before
// making pipelines (GccPhat picks its direct-sum threshold from the lanes at construction).
void set_simd_target(const std::string& name);
// The target the kernels dispatch to now, by Highway's name ("AVX3", "AVX2", "NEON", ...).
std::string simd_target_name();
// Doubles per vector of that target (2 on SSE4 and NEON, 4 on AVX2, 8 on AVX3).
int simd_double_lanes();
// Kernel calls served since start-up by the target named (all targets for ""): counts, not
// times, so that a run under emulation can show which code ran.
std::uint64_t simd_dispatch_count(const std::string& target_name = "");

namespace simd {
// Counts one call of a kernel compiled for `target` (a Highway target bit); called by the
// kernels themselves.
void note_dispatch(std::int64_t target);
}  // namespace simd

}  // namespace dronetrack::doa
