#include "apps/heap_trim.hpp"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace dronetrack::apps {

void HeapTrim::poll() {
  const auto now = std::chrono::steady_clock::now();
  if (now - last_ < period_) return;
  last_ = now;
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace dronetrack::apps
