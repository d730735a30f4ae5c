#include "apps/line_history.hpp"

#include <cstring>

namespace dronetrack::apps {

void LineHistory::drop_oldest() {
  first_ = (first_ + 1) % entries_.size();
  --count_;
}

void LineHistory::add(double time_s, const char* text, std::size_t length) {
  if (length > text_.size() || entries_.empty()) return;
  if (write_ + length > text_.size()) write_ = 0;  // the tail end stays unused this round
  // Text is written in order, so the lines right after write_ are the oldest: drop those the
  // new line overwrites (checking the oldest suffices), and one if the index is full.
  while (count_ > 0) {
    const Entry& oldest = entries_[first_];
    const bool overlaps = oldest.offset < write_ + length && write_ < oldest.offset + oldest.length;
    if (!overlaps && count_ < entries_.size()) break;
    drop_oldest();
  }
  std::memcpy(text_.data() + write_, text, length);
  entries_[(first_ + count_) % entries_.size()] = {time_s, write_, length};
  ++count_;
  write_ += length;
}

void LineHistory::drop_before(double time_s) {
  while (count_ > 0 && entries_[first_].time_s < time_s) drop_oldest();
}

}  // namespace dronetrack::apps
