#pragma once
// HTTP Basic authentication of operators against a users file (user_file.hpp). Basic, over the
// server's TLS, because a browser sends it with every request of the page, event streams
// included, with no login page or cookie to get wrong; scripts use `curl -u`.
// A password is checked with PBKDF2 once; afterwards a keyed digest of it (HMAC-SHA256 under a
// per-process random key) is remembered per user, so the page's requests cost a hash, not
// 0.2 s each. The users file is re-read when it changes (checked at most once a second): a
// user removed from it (revoked) is refused from then on. A file that no longer parses refuses
// everyone until it is mended (fail closed), and says why in last_error().
#include <array>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>

#include "http_api/user_file.hpp"

namespace dronetrack::http_api {

class Authenticator {
 public:
  enum class Result { accepted, missing, rejected };

  // Reads the file; throws std::runtime_error naming the file and line if it cannot.
  explicit Authenticator(std::filesystem::path users_file);

  // `authorization` is the request's Authorization header value ("" if absent). On
  // `accepted`, `user` is the user's name.
  Result check(std::string_view authorization, std::string& user);
  // Why the users file was last refused ("" while it reads fine).
  std::string last_error();

 private:
  using Digest = std::array<unsigned char, 32>;
  void reload_if_changed();
  Digest keyed_digest(std::string_view user, std::string_view password) const;

  const std::filesystem::path file_;
  std::array<unsigned char, 32> process_key_{};
  std::mutex mutex_;
  // Shared, never changed once read: a slow check holds the users it started with while a
  // reload swaps in new ones, without copying the file per check.
  std::shared_ptr<const UserFile> users_;
  bool usable_ = true;
  std::string last_error_;
  std::filesystem::file_time_type modified_{};
  std::uintmax_t size_ = 0;
  std::chrono::steady_clock::time_point next_check_{};
  std::uint64_t generation_ = 0;  // counts reloads: a check that spans one caches nothing
  std::unordered_map<std::string, Digest> verified_;  // user -> keyed digest of its password
};

// "Basic <base64 of user:password>" -> user and password; false if it is not that.
bool parse_basic_authorization(std::string_view header, std::string& user, std::string& password);

}  // namespace dronetrack::http_api
