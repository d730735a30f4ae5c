#pragma once
// Track ids no fusion restart reuses (docs/contract.md, "Track ids across restarts"). The
// engine numbers its tracks 1, 2, ... in every instance; on the wire (Track, Alert, track
// lines, web API) each id is offset by a base read from a small state file that holds the
// first id no instance has reserved. Ids are reserved in blocks: the file is rewritten
// (temporary, fsync, rename) before an id of a new block goes out, so after a crash or a
// SIGKILL the next instance starts above every id the last one could have published; at most a
// block is skipped. Without a file the base is 0 (ids as the engine numbers them).
#include <cstdint>
#include <filesystem>

namespace dronetrack::apps {

class TrackIdReservation {
 public:
  static constexpr std::int64_t kBlock = 1024;

  // Reads the file (missing: first instance, ids from 1) and reserves the first block. Throws
  // UserError on a file that does not hold one id, or OutputError when it cannot be written.
  explicit TrackIdReservation(std::filesystem::path file = {});

  // The wire id of the engine's track `engine_id` (>= 1). Extends the reservation first when
  // the id is past it; a failed write is logged (the track still goes out: an operator must
  // see it) and retried at the next id.
  int wire_id(int engine_id);
  std::int64_t base() const { return base_; }
  std::int64_t reserved_until() const { return reserved_; }

 private:
  void reserve(std::int64_t until);

  std::filesystem::path file_;
  std::int64_t base_ = 0;       // wire id = base_ + engine id (wrapped past INT32_MAX)
  std::int64_t reserved_ = 0;   // ids below this are covered by the file
  std::int64_t failed_at_ = 0;  // the id whose reservation last failed to be written
};

}  // namespace dronetrack::apps
