// LineHistory (the incident recorder's last lines in fixed memory): lines come back in order,
// the oldest go when the text or the index is full or by time, and wrapping keeps every line whole.
#include "apps/line_history.hpp"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace dronetrack::apps {
namespace {

std::vector<std::string> lines_of(const LineHistory& history, double from_s = -1e9,
                                  double to_s = 1e9) {
  std::vector<std::string> lines;
  history.for_each(from_s, to_s,
                   [&](const char* text, std::size_t length) { lines.emplace_back(text, length); });
  return lines;
}

void add(LineHistory& history, double time_s, const std::string& text) {
  history.add(time_s, text.data(), text.size());
}

TEST(LineHistory, KeepsTheNewestLinesWholeAcrossWrapAround) {
  LineHistory history(32, 100);  // 32 bytes of text
  for (int i = 0; i < 20; ++i) add(history, i, "line" + std::to_string(i) + "...");  // 9-10 bytes
  const std::vector<std::string> kept = lines_of(history);
  ASSERT_FALSE(kept.empty());
  EXPECT_EQ(kept.back(), "line19...");
  // Consecutive, newest last, each whole.
  for (std::size_t i = 0; i < kept.size(); ++i)
    EXPECT_EQ(kept[i], "line" + std::to_string(20 - kept.size() + i) + "...");
  EXPECT_LE(kept.size(), 3u);
  EXPECT_EQ(lines_of(history, 19.0, 19.0), std::vector<std::string>{"line19..."});
}

TEST(LineHistory, IndexFullDropsTheOldestAndTimeTrims) {
  LineHistory history(1000, 3);
  for (int i = 0; i < 5; ++i) add(history, i, std::to_string(i));
  EXPECT_EQ(lines_of(history), (std::vector<std::string>{"2", "3", "4"}));
  history.drop_before(4.0);
  EXPECT_EQ(lines_of(history), std::vector<std::string>{"4"});
  add(history, 5, std::string(2000, 'x'));  // longer than the buffer: not kept
  EXPECT_EQ(history.size(), 1u);
}

}  // namespace
}  // namespace dronetrack::apps
