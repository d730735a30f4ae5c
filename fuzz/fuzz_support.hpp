#pragma once
// Helpers shared by the harnesses: an input as a file our readers open by path (they take file
// names, as the command line gives them), and a reader turning fuzz bytes into typed fields.
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace dronetrack::fuzz {

// A failed property of the code under test: says which and aborts, which libFuzzer reports as
// a crash and saves the input (and fails a corpus replay under ctest).
[[noreturn]] inline void fail(const char* what) {
  std::fprintf(stderr, "fuzz property violated: %s\n", what);
  std::abort();
}

// Every problem a reader reports is printed as one line: none empty, none spanning two.
inline void check_lines(const std::vector<std::string>& lines) {
  for (const std::string& line : lines) {
    if (line.empty()) fail("empty problem line");
    if (line.find_first_of("\r\n") != std::string::npos) fail("problem spans several lines");
  }
}

// The input as an in-memory file, reachable by path (/proc/self/fd/N) as long as this lives.
// One per process, rewritten for each input: no disk I/O, nothing left behind.
class MemoryFile {
 public:
  MemoryFile() : fd_(::memfd_create("dronetrack-fuzz", 0)) {
    if (fd_ < 0) fail("memfd_create");
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  ~MemoryFile() { ::close(fd_); }
  MemoryFile(const MemoryFile&) = delete;
  MemoryFile& operator=(const MemoryFile&) = delete;

  const std::string& write(const std::uint8_t* data, std::size_t size) {
    if (::ftruncate(fd_, 0) != 0 || ::lseek(fd_, 0, SEEK_SET) != 0) fail("memfd reset");
    std::size_t done = 0;
    while (done < size) {
      const ssize_t n = ::write(fd_, data + done, size - done);
      if (n <= 0) fail("memfd write");
      done += static_cast<std::size_t>(n);
    }
    return path_;
  }

 private:
  int fd_;
  std::string path_;
};

// Consumes the input front to back; past its end every field reads as zero, so any input is a
// complete sample.
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}

  template <typename T>
  T take() {
    T value{};
    const std::size_t n = std::min(sizeof(T), size_ - used_);
    if (n > 0) std::memcpy(&value, data_ + used_, n);
    used_ += n;
    return value;
  }
  bool flag() { return (take<std::uint8_t>() & 1U) != 0; }
  // Mostly values a sender could mean (small, signed, fractional), sometimes NaN, +-inf, the
  // extremes or raw bit patterns: the validation must catch every one.
  double number() {
    const auto kind = take<std::uint8_t>();
    switch (kind % 8) {
      case 0:
        return std::numeric_limits<double>::quiet_NaN();
      case 1:
        return (kind & 8U) ? std::numeric_limits<double>::infinity()
                           : -std::numeric_limits<double>::infinity();
      case 2:
        return (kind & 8U) ? std::numeric_limits<double>::max()
                           : std::numeric_limits<double>::denorm_min();
      case 3:
        return take<double>();
      default:
        return static_cast<double>(take<std::int16_t>()) / 256.0;
    }
  }
  template <std::size_t N>
  void numbers(double (&out)[N]) {
    for (double& value : out) value = number();
  }
  // A fixed IDL string: `length` bytes from the input (maybe no terminator at all).
  template <std::size_t N>
  void text(char (&out)[N]) {
    std::memset(out, 0, N);
    const std::size_t length = std::min<std::size_t>(take<std::uint8_t>(), N);
    for (std::size_t i = 0; i < length; ++i) out[i] = take<char>();
  }
  std::size_t remaining() const { return size_ - used_; }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t used_ = 0;
};

}  // namespace dronetrack::fuzz
