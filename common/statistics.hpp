#pragma once
// Order statistics that calibration, health checks, benches and tests share: header-only, no
// allocation in the in-place form, so the node's per-frame checks may use it.

#include <algorithm>
#include <cstddef>
#include <limits>
#include <span>
#include <vector>

namespace dronetrack {

// The median of `values`, which it reorders: the middle value, or the mean of the two middle
// values of an even count. NaN for none.
inline double median_in_place(std::span<double> values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t half = values.size() / 2;
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(half);
  std::nth_element(values.begin(), middle, values.end());
  if (values.size() % 2 == 1) return *middle;
  // nth_element leaves the lower half before `middle`: its largest is the other middle value.
  return 0.5 * (*std::max_element(values.begin(), middle) + *middle);
}

// The median of a copy of `values`; NaN for none.
inline double median(std::vector<double> values) { return median_in_place(values); }

}  // namespace dronetrack
