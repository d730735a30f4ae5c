#pragma once
// The server side of TLS for the operator's HTTP server: one OpenSSL SSL_CTX made from a PEM
// certificate chain and its private key, shared by every connection. Only TLS 1.2 and 1.3 are
// offered (OpenSSL 3's default cipher lists, which carry forward secrecy).
#include <filesystem>

struct ssl_ctx_st;  // OpenSSL's SSL_CTX: callers need not include <openssl/ssl.h>

namespace dronetrack::http_api {

class TlsContext {
 public:
  // Throws std::runtime_error naming the file and what is wrong with it (unreadable, not PEM,
  // the key does not match the certificate).
  TlsContext(const std::filesystem::path& certificate_chain_pem,
             const std::filesystem::path& private_key_pem);
  ~TlsContext();
  TlsContext(const TlsContext&) = delete;
  TlsContext& operator=(const TlsContext&) = delete;

  ssl_ctx_st* native() const { return context_; }

 private:
  ssl_ctx_st* context_ = nullptr;
};

}  // namespace dronetrack::http_api
