#include "http_api/authenticator.hpp"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>

#include <cctype>
#include <stdexcept>
#include <vector>

namespace dronetrack::http_api {
namespace {

constexpr auto kRecheckInterval = std::chrono::seconds(1);

}  // namespace

bool parse_basic_authorization(std::string_view header, std::string& user, std::string& password) {
  constexpr std::string_view kScheme = "basic ";
  if (header.size() <= kScheme.size()) return false;
  for (std::size_t i = 0; i < kScheme.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(header[i])) != kScheme[i]) return false;
  }
  std::string_view encoded = header.substr(kScheme.size());
  while (!encoded.empty() && encoded.front() == ' ') encoded.remove_prefix(1);
  while (!encoded.empty() && encoded.back() == ' ') encoded.remove_suffix(1);
  if (encoded.empty() || encoded.size() % 4 != 0 || encoded.size() > 4096) return false;
  for (char c : encoded) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '+' || c == '/' || c == '=')) {
      return false;
    }
  }
  std::vector<unsigned char> decoded(encoded.size() / 4 * 3 + 1);
  const int length =
      EVP_DecodeBlock(decoded.data(), reinterpret_cast<const unsigned char*>(encoded.data()),
                      static_cast<int>(encoded.size()));
  if (length < 0) return false;
  // EVP_DecodeBlock counts the padding as zero bytes.
  std::size_t size = static_cast<std::size_t>(length);
  for (std::size_t i = encoded.size(); i > 0 && encoded[i - 1] == '='; --i) --size;
  const std::string_view text(reinterpret_cast<const char*>(decoded.data()), size);
  const auto colon = text.find(':');
  if (colon == std::string_view::npos) return false;
  user = std::string(text.substr(0, colon));
  password = std::string(text.substr(colon + 1));
  return true;
}

Authenticator::Authenticator(std::filesystem::path users_file) : file_(std::move(users_file)) {
  if (RAND_bytes(process_key_.data(), static_cast<int>(process_key_.size())) != 1) {
    throw std::runtime_error("no random bytes for the credential cache key");
  }
  users_ = std::make_shared<const UserFile>(UserFile::load(file_));
  std::error_code error;
  modified_ = std::filesystem::last_write_time(file_, error);
  size_ = std::filesystem::file_size(file_, error);
  next_check_ = std::chrono::steady_clock::now() + kRecheckInterval;
}

Authenticator::Digest Authenticator::keyed_digest(std::string_view user,
                                                  std::string_view password) const {
  std::string message(user);
  message += '\0';
  message += password;
  Digest digest{};
  unsigned int length = 0;
  HMAC(EVP_sha256(), process_key_.data(), static_cast<int>(process_key_.size()),
       reinterpret_cast<const unsigned char*>(message.data()), message.size(), digest.data(),
       &length);
  return digest;
}

void Authenticator::reload_if_changed() {
  const auto now = std::chrono::steady_clock::now();
  if (now < next_check_) return;
  next_check_ = now + kRecheckInterval;
  std::error_code error;
  const auto modified = std::filesystem::last_write_time(file_, error);
  const auto size = error ? 0 : std::filesystem::file_size(file_, error);
  if (!error && usable_ && modified == modified_ && size == size_) return;
  modified_ = modified;
  size_ = size;
  verified_.clear();
  ++generation_;
  try {
    users_ = std::make_shared<const UserFile>(UserFile::load(file_));
    usable_ = true;
    last_error_.clear();
  } catch (const std::exception& e) {
    users_ = std::make_shared<const UserFile>();
    usable_ = false;
    last_error_ = e.what();
  }
}

Authenticator::Result Authenticator::check(std::string_view authorization, std::string& user) {
  std::string name;
  std::string password;
  if (authorization.empty()) return Result::missing;
  if (!parse_basic_authorization(authorization, name, password)) return Result::rejected;
  const Digest digest = keyed_digest(name, password);
  {
    std::lock_guard lock(mutex_);
    reload_if_changed();
    if (!usable_) return Result::rejected;
    const auto it = verified_.find(name);
    if (it != verified_.end() && CRYPTO_memcmp(it->second.data(), digest.data(), 32) == 0) {
      user = name;
      return Result::accepted;
    }
  }
  // PBKDF2 outside the lock: one slow check must not hold up every other request. The users
  // read here may be replaced meanwhile; the cache entry is then dropped by the next reload.
  std::shared_ptr<const UserFile> users;
  std::uint64_t generation = 0;
  {
    std::lock_guard lock(mutex_);
    users = users_;
    generation = generation_;
  }
  if (!users->verify(name, password)) return Result::rejected;
  std::lock_guard lock(mutex_);
  if (generation == generation_) verified_[name] = digest;
  user = name;
  return Result::accepted;
}

std::string Authenticator::last_error() {
  std::lock_guard lock(mutex_);
  return last_error_;
}

}  // namespace dronetrack::http_api
