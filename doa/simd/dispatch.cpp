// Highway's run-time dispatch made visible: which target the kernels run, forcing one, and how
// many calls each target served.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "doa/simd/dispatch.cpp"
#include "hwy/foreach_target.h"  // IWYU pragma: keep
// foreach_target.h re-includes this file per target.
#include "doa/simd/dispatch.hpp"
#include "hwy/highway.h"

HWY_BEFORE_NAMESPACE();
namespace dronetrack::doa::simd::HWY_NAMESPACE {
namespace {
std::int64_t TargetOfDispatch() { return HWY_TARGET; }
int DoubleLanes() {
  return static_cast<int>(hwy::HWY_NAMESPACE::Lanes(hwy::HWY_NAMESPACE::ScalableTag<double>()));
}
}  // namespace
}  // namespace dronetrack::doa::simd::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#include <array>
#include <atomic>
#include <stdexcept>

namespace dronetrack::doa {

namespace simd {
namespace {
HWY_EXPORT(TargetOfDispatch);
HWY_EXPORT(DoubleLanes);

// One counter per target bit.
std::array<std::atomic<std::uint64_t>, 64>& dispatch_counts() {
  static std::array<std::atomic<std::uint64_t>, 64> counts{};
  return counts;
}

std::int64_t chosen_target() { return HWY_DYNAMIC_DISPATCH(TargetOfDispatch)(); }
int double_lanes() { return HWY_DYNAMIC_DISPATCH(DoubleLanes)(); }
}  // namespace

void note_dispatch(std::int64_t target) {
  const auto bit = hwy::Num0BitsBelowLS1Bit_Nonzero64(static_cast<std::uint64_t>(target));
  // A load and a store, not a locked add: kernels run per bin row many times a frame, and the
  // counts only need to show which target ran (two threads may lose an increment, never the
  // fact).
  std::atomic<std::uint64_t>& count = dispatch_counts()[bit];
  count.store(count.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}
}  // namespace simd

void set_simd_target(const std::string& name) {
  hwy::SetSupportedTargetsForTest(0);  // the CPU's own list first
  if (name.empty() || name == "auto") {
    hwy::GetChosenTarget().Update(hwy::SupportedTargets());
    return;
  }
  const std::string wanted = name == "AVX512" || name == "AVX-512" ? "AVX3" : name;
  std::string available;
  for (const std::int64_t target : hwy::SupportedAndGeneratedTargets()) {
    if (wanted == hwy::TargetName(target)) {
      hwy::SetSupportedTargetsForTest(target);
      hwy::GetChosenTarget().Update(hwy::SupportedTargets());
      return;
    }
    available += std::string(available.empty() ? "" : ", ") + hwy::TargetName(target);
  }
  hwy::GetChosenTarget().Update(hwy::SupportedTargets());
  throw std::invalid_argument("simd target '" + name + "' not available here (" + available + ")");
}

std::string simd_target_name() { return hwy::TargetName(simd::chosen_target()); }

int simd_double_lanes() { return simd::double_lanes(); }

std::uint64_t simd_dispatch_count(const std::string& target_name) {
  std::uint64_t total = 0;
  for (int bit = 0; bit < 64; ++bit) {
    const std::int64_t target = std::int64_t{1} << bit;
    if (target_name.empty() || target_name == hwy::TargetName(target))
      total +=
          simd::dispatch_counts()[static_cast<std::size_t>(bit)].load(std::memory_order_relaxed);
  }
  return total;
}

}  // namespace dronetrack::doa
#endif
