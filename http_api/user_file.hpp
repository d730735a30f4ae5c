#pragma once
// The operator accounts of the HTTP server: a text file of one user per line,
//   name:pbkdf2-sha256:ITERATIONS:SALT_HEX:HASH_HEX
// (blank lines and lines starting with '#' are ignored). Only salted PBKDF2-HMAC-SHA256
// hashes are stored, never a password; `dronetrack passwd` writes the lines. The file is named
// by the site config (http.users_file), so no secret lives in the config itself.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace dronetrack::http_api {

struct UserEntry {
  std::string name;
  std::uint32_t iterations = 0;
  std::vector<unsigned char> salt{};
  std::vector<unsigned char> hash{};
};

// 600,000 iterations: OWASP's 2023 figure for PBKDF2-HMAC-SHA256 (~0.2 s on a node's core; the
// server verifies a password once and then remembers it, docs/http_api.md "Access").
inline constexpr std::uint32_t kDefaultPasswordIterations = 600000;
// Fewer iterations are refused when a file is read: such a hash falls to a GPU in hours.
inline constexpr std::uint32_t kMinimumPasswordIterations = 100000;
// A users file line is ~150 bytes: 1 MiB holds thousands of operators, and a wrong path (a log,
// a disk image) is refused before it is read into memory.
inline constexpr std::size_t kMaxUserFileBytes = 1u << 20;

class UserFile {
 public:
  UserFile() = default;
  // Throws std::runtime_error "FILE:LINE: what is wrong" (or "FILE: cannot read").
  static UserFile load(const std::filesystem::path& file);
  // The same from text; `origin` names it in errors.
  static UserFile parse(std::string_view text, const std::string& origin);

  // True if `name` is a user and `password` its password (constant-time comparison).
  bool verify(std::string_view name, std::string_view password) const;
  const std::vector<UserEntry>& users() const { return users_; }

 private:
  std::vector<UserEntry> users_;
};

// A line for the file: a fresh random 16-byte salt. Throws if the name is not a plain name
// (letters, digits, '.', '_', '-'; 1..64 characters) or the password is empty.
std::string make_user_line(std::string_view name, std::string_view password,
                           std::uint32_t iterations = kDefaultPasswordIterations);

// True for a name make_user_line accepts.
bool valid_user_name(std::string_view name);

}  // namespace dronetrack::http_api
