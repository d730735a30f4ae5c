#include "common/input_file.hpp"

#include <fstream>
#include <stdexcept>
#include <system_error>

namespace dronetrack {

std::string read_text_file(const std::filesystem::path& file, std::size_t max_bytes,
                           const std::string& what) {
  std::error_code error;
  if (std::filesystem::is_directory(file, error))
    throw std::runtime_error(file.string() + ": is a directory, not a " + what);
  std::ifstream stream(file, std::ios::binary);
  if (!stream) throw std::runtime_error(file.string() + ": cannot open " + what);
  const auto size = std::filesystem::file_size(file, error);
  const std::string limit = max_bytes >= (1u << 20) ? std::to_string(max_bytes >> 20) + " MiB"
                                                    : std::to_string(max_bytes >> 10) + " kB";
  if (!error && size > max_bytes) {
    throw std::runtime_error(file.string() + ": " + std::to_string(size) + " bytes; a " + what +
                             " may be at most " + limit);
  }
  // Read in bounded chunks: a FIFO or /proc file has no size to check up front.
  std::string text;
  char chunk[65536];
  while (stream.read(chunk, sizeof chunk) || stream.gcount() > 0) {
    text.append(chunk, static_cast<std::size_t>(stream.gcount()));
    if (text.size() > max_bytes)
      throw std::runtime_error(file.string() + ": larger than " + limit + "; a " + what +
                               " may be at most that");
  }
  if (stream.bad()) throw std::runtime_error(file.string() + ": read error");
  return text;
}

}  // namespace dronetrack
