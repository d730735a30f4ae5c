#pragma once
// One spelling of a lane shuffle of two GCC-style vectors for GCC and clang: GCC's
// __builtin_shuffle takes the lane indices as a vector, clang only has __builtin_shufflevector
// with constant indices (clang builds the fuzz harnesses, fuzz/README.md). Indices 0..N-1 pick
// lanes of `a`, N..2N-1 lanes of `b`; the result has as many lanes as indices given.
#if defined(__clang__)
// sizeof: the selector type is named on both sides, so neither compiler finds it unused.
#define DRONETRACK_SHUFFLE(a, b, Selector, ...) \
  (static_cast<void>(sizeof(Selector)), __builtin_shufflevector(a, b, __VA_ARGS__))
#else
#define DRONETRACK_SHUFFLE(a, b, Selector, ...) __builtin_shuffle(a, b, Selector{__VA_ARGS__})
#endif
