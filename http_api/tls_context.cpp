#include "http_api/tls_context.hpp"

#include <openssl/err.h>
#include <openssl/ssl.h>

#include <stdexcept>
#include <string>

namespace dronetrack::http_api {
namespace {

// The newest OpenSSL error as text ("no start line", "key values mismatch"), or `fallback`.
std::string openssl_reason(const char* fallback) {
  const unsigned long code = ERR_peek_last_error();
  ERR_clear_error();
  if (code == 0) return fallback;
  const char* reason = ERR_reason_error_string(code);
  return reason != nullptr ? reason : fallback;
}

}  // namespace

TlsContext::TlsContext(const std::filesystem::path& certificate_chain_pem,
                       const std::filesystem::path& private_key_pem) {
  ERR_clear_error();
  context_ = SSL_CTX_new(TLS_server_method());
  if (context_ == nullptr) throw std::runtime_error("TLS: " + openssl_reason("no SSL context"));
  const auto fail = [this](const std::string& message) {
    SSL_CTX_free(context_);
    context_ = nullptr;
    throw std::runtime_error(message);
  };
  SSL_CTX_set_min_proto_version(context_, TLS1_2_VERSION);
  // A peer that vanishes mid-write must not kill the process; the server also sends with
  // MSG_NOSIGNAL, but OpenSSL writes through its own BIO.
  SSL_CTX_set_mode(context_, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
  if (SSL_CTX_use_certificate_chain_file(context_, certificate_chain_pem.c_str()) != 1) {
    fail("TLS certificate " + certificate_chain_pem.string() + ": " +
         openssl_reason("cannot read a PEM certificate"));
  }
  if (SSL_CTX_use_PrivateKey_file(context_, private_key_pem.c_str(), SSL_FILETYPE_PEM) != 1) {
    fail("TLS private key " + private_key_pem.string() + ": " +
         openssl_reason("cannot read a PEM private key"));
  }
  if (SSL_CTX_check_private_key(context_) != 1) {
    fail("TLS private key " + private_key_pem.string() + " does not match certificate " +
         certificate_chain_pem.string());
  }
}

TlsContext::~TlsContext() { SSL_CTX_free(context_); }

}  // namespace dronetrack::http_api
