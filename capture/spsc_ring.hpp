#pragma once
// A bounded single-producer/single-consumer ring of preallocated slots, lock-free and
// allocation-free after construction: the audio callback (producer) fills a slot in place and
// publishes it; the consumer thread reads it in place and releases it. Neither side ever waits
// for the other, so the callback cannot be blocked by a slow consumer: when the ring is full
// try_begin_write() returns nullptr and the producer drops its data (and counts it).
//
// Exactly one thread may call the producer pair (try_begin_write/end_write) and exactly one the
// consumer pair (try_begin_read/end_read); the two may be different threads.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace dronetrack::capture {

template <class Slot>
class SpscRing {
 public:
  // Every slot starts as a copy of `prototype` (e.g. a block with its sample buffer sized).
  SpscRing(std::size_t capacity, const Slot& prototype) : slots_(capacity, prototype) {
    if (capacity == 0) throw std::invalid_argument("SpscRing: capacity must be at least 1");
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  std::size_t capacity() const { return slots_.size(); }
  // Exact when called from either side while the other is idle; a snapshot otherwise.
  std::size_t size() const {
    return static_cast<std::size_t>(written_.load(std::memory_order_acquire) -
                                    read_.load(std::memory_order_acquire));
  }

  // Producer: the next free slot, or nullptr if the consumer has not released one yet.
  Slot* try_begin_write() {
    const std::uint64_t written = written_.load(std::memory_order_relaxed);
    // Acquire pairs with end_read(): the consumer is done reading the slot we may reuse.
    if (written - read_.load(std::memory_order_acquire) == slots_.size()) return nullptr;
    return &slots_[static_cast<std::size_t>(written % slots_.size())];
  }
  // Producer: publish the slot returned by the last successful try_begin_write().
  void end_write() {
    // Release: the slot's contents are visible before the consumer sees the new count.
    written_.store(written_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }

  // Consumer: the oldest published slot, or nullptr if none is ready.
  Slot* try_begin_read() {
    const std::uint64_t read = read_.load(std::memory_order_relaxed);
    if (written_.load(std::memory_order_acquire) == read) return nullptr;
    return &slots_[static_cast<std::size_t>(read % slots_.size())];
  }
  // Consumer: hand the slot returned by the last successful try_begin_read() back.
  void end_read() {
    read_.store(read_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }

 private:
  // 64 bytes: the cache line of x86-64 and most ARM cores. Keeping the two counters on separate
  // lines stops the producer and consumer from invalidating each other's line on every step.
  static constexpr std::size_t kCacheLine = 64;

  std::vector<Slot> slots_;
  // Monotonic counts (not wrapped indices), so full (difference == capacity) and empty
  // (difference == 0) are distinguishable without a spare slot; 2^64 never wraps in practice.
  alignas(kCacheLine) std::atomic<std::uint64_t> written_{0};
  alignas(kCacheLine) std::atomic<std::uint64_t> read_{0};
};

}  // namespace dronetrack::capture
