#pragma once
// The last lines of an output (DOA or track lines) with their times, in fixed memory: text in one
// circular buffer, lines in a circular index; a new line overwrites the oldest ones when either is
// full. add() never allocates (the incident recorder keeps every DOA of the last minutes).
#include <cstddef>
#include <vector>

namespace dronetrack::apps {

class LineHistory {
 public:
  LineHistory(std::size_t text_bytes, std::size_t max_lines)
      : text_(text_bytes), entries_(max_lines) {}

  // A line longer than the whole buffer is not kept.
  void add(double time_s, const char* text, std::size_t length);
  // Forgets lines older than `time_s` (from the oldest on: lines come roughly in time order).
  void drop_before(double time_s);
  // Calls each(text, length) for every line with a time in [from_s, to_s], oldest first.
  template <class Each>
  void for_each(double from_s, double to_s, Each&& each) const {
    for (std::size_t i = 0; i < count_; ++i) {
      const Entry& entry = entries_[(first_ + i) % entries_.size()];
      if (entry.time_s >= from_s && entry.time_s <= to_s)
        each(text_.data() + entry.offset, entry.length);
    }
  }
  std::size_t size() const { return count_; }

 private:
  struct Entry {
    double time_s = 0.0;
    std::size_t offset = 0;
    std::size_t length = 0;
  };
  void drop_oldest();

  std::vector<char> text_;
  std::vector<Entry> entries_;
  std::size_t first_ = 0;  // oldest entry
  std::size_t count_ = 0;
  std::size_t write_ = 0;  // where the next line's text goes
};

}  // namespace dronetrack::apps
