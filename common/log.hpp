#pragma once
// Levelled logging to stderr. JSON-lines outputs never go through here: they go to files or
// stdout. Thread-safe (one line per call, never interleaved). Arguments are streamed:
//   log::warn("array ", id, ": ", count, " NaN samples replaced");
#include <sstream>
#include <string>
#include <string_view>

namespace dronetrack::log {

enum class Level { debug = 0, info = 1, warn = 2, error = 3, off = 4 };

void set_level(Level level);
Level level();
// Parses "debug|info|warn|error|off"; returns false on anything else.
bool parse_level(std::string_view text, Level& out);
void write(Level level, std::string_view message);

template <class... Args>
void emit(Level at, const Args&... args) {
  if (level() > at) return;
  std::ostringstream line;
  (line << ... << args);
  write(at, line.str());
}
template <class... Args>
void debug(const Args&... args) {
  emit(Level::debug, args...);
}
template <class... Args>
void info(const Args&... args) {
  emit(Level::info, args...);
}
template <class... Args>
void warn(const Args&... args) {
  emit(Level::warn, args...);
}
template <class... Args>
void error(const Args&... args) {
  emit(Level::error, args...);
}

}  // namespace dronetrack::log
