#include "http_api/user_file.hpp"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/rand.h>

#include <charconv>
#include <stdexcept>

#include "common/input_file.hpp"

namespace dronetrack::http_api {
namespace {

constexpr std::string_view kScheme = "pbkdf2-sha256";
constexpr std::size_t kSaltBytes = 16;
constexpr std::size_t kHashBytes = 32;

std::vector<unsigned char> pbkdf2(std::string_view password, const std::vector<unsigned char>& salt,
                                  std::uint32_t iterations, std::size_t bytes) {
  std::vector<unsigned char> out(bytes);
  if (PKCS5_PBKDF2_HMAC(password.data(), static_cast<int>(password.size()), salt.data(),
                        static_cast<int>(salt.size()), static_cast<int>(iterations), EVP_sha256(),
                        static_cast<int>(out.size()), out.data()) != 1) {
    throw std::runtime_error("PBKDF2 failed");
  }
  return out;
}

std::string to_hex(const std::vector<unsigned char>& bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(bytes.size() * 2);
  for (unsigned char b : bytes) {
    out += kDigits[b >> 4];
    out += kDigits[b & 15];
  }
  return out;
}

bool from_hex(std::string_view text, std::vector<unsigned char>& out) {
  if (text.empty() || text.size() % 2 != 0) return false;
  out.clear();
  for (std::size_t i = 0; i < text.size(); i += 2) {
    unsigned value = 0;
    const auto [end, error] = std::from_chars(text.data() + i, text.data() + i + 2, value, 16);
    if (error != std::errc() || end != text.data() + i + 2) return false;
    out.push_back(static_cast<unsigned char>(value));
  }
  return true;
}

std::vector<std::string_view> split(std::string_view line, char separator) {
  std::vector<std::string_view> fields;
  std::size_t begin = 0;
  for (;;) {
    const std::size_t end = line.find(separator, begin);
    fields.push_back(line.substr(begin, end == std::string_view::npos ? end : end - begin));
    if (end == std::string_view::npos) return fields;
    begin = end + 1;
  }
}

}  // namespace

bool valid_user_name(std::string_view name) {
  if (name.empty() || name.size() > 64) return false;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

UserFile UserFile::load(const std::filesystem::path& file) {
  return parse(read_text_file(file, kMaxUserFileBytes, "users file"), file.string());
}

UserFile UserFile::parse(std::string_view text, const std::string& origin) {
  UserFile result;
  std::size_t line_number = 0;
  std::size_t begin = 0;
  while (begin < text.size()) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(begin, end - begin);
    begin = end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line.front() == '#') continue;
    const auto fail = [&](const std::string& what) {
      throw std::runtime_error(origin + ":" + std::to_string(line_number) + ": " + what);
    };
    const auto fields = split(line, ':');
    if (fields.size() != 5) {
      fail("expected name:pbkdf2-sha256:ITERATIONS:SALT_HEX:HASH_HEX (5 fields), got " +
           std::to_string(fields.size()));
    }
    UserEntry entry;
    entry.name = std::string(fields[0]);
    if (!valid_user_name(entry.name)) {
      fail("user name must be 1-64 letters, digits, '.', '_' or '-'");
    }
    if (fields[1] != kScheme) fail("unknown hash scheme '" + std::string(fields[1]) + "'");
    const auto [stop, error] =
        std::from_chars(fields[2].data(), fields[2].data() + fields[2].size(), entry.iterations);
    if (error != std::errc() || stop != fields[2].data() + fields[2].size()) {
      fail("iterations must be a whole number");
    }
    if (entry.iterations < kMinimumPasswordIterations) {
      fail("iterations " + std::to_string(entry.iterations) + " below the minimum " +
           std::to_string(kMinimumPasswordIterations));
    }
    if (!from_hex(fields[3], entry.salt) || entry.salt.size() < 8) {
      fail("salt must be at least 8 bytes of hex");
    }
    if (!from_hex(fields[4], entry.hash) || entry.hash.size() != kHashBytes) {
      fail("hash must be 32 bytes of hex");
    }
    for (const UserEntry& other : result.users_) {
      if (other.name == entry.name) fail("user '" + entry.name + "' appears twice");
    }
    result.users_.push_back(std::move(entry));
  }
  return result;
}

bool UserFile::verify(std::string_view name, std::string_view password) const {
  for (const UserEntry& entry : users_) {
    if (entry.name != name) continue;
    const auto hash = pbkdf2(password, entry.salt, entry.iterations, entry.hash.size());
    return CRYPTO_memcmp(hash.data(), entry.hash.data(), hash.size()) == 0;
  }
  return false;
}

std::string make_user_line(std::string_view name, std::string_view password,
                           std::uint32_t iterations) {
  if (!valid_user_name(name)) {
    throw std::runtime_error("user name '" + std::string(name) +
                             "' must be 1-64 letters, digits, '.', '_' or '-'");
  }
  if (password.empty()) throw std::runtime_error("empty password");
  if (iterations < kMinimumPasswordIterations) {
    throw std::runtime_error("iterations below " + std::to_string(kMinimumPasswordIterations));
  }
  std::vector<unsigned char> salt(kSaltBytes);
  if (RAND_bytes(salt.data(), static_cast<int>(salt.size())) != 1) {
    throw std::runtime_error("no random bytes for a salt");
  }
  const auto hash = pbkdf2(password, salt, iterations, kHashBytes);
  return std::string(name) + ":" + std::string(kScheme) + ":" + std::to_string(iterations) + ":" +
         to_hex(salt) + ":" + to_hex(hash);
}

}  // namespace dronetrack::http_api
