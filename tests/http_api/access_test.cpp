// Operator access beyond loopback (issue 18): HTTPS, users with hashed passwords, per-client
// limits, and the refusal to expose the API without them. Real TLS over loopback with a
// certificate made here, real httplib clients.
#include <gtest/gtest.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include "http_api/authenticator.hpp"
#include "http_api/client_address.hpp"
#include "http_api/client_budget.hpp"
#include "http_api/http_server.hpp"
#include "http_api/user_file.hpp"
#include "tests/http_api/raw_client.hpp"
#include "tests/http_api/test_support.hpp"

// After the Eigen-using headers: <httplib.h> pulls in <resolv.h>, whose `_res` macro breaks
// Eigen.
#include <httplib.h>

namespace dronetrack::http_api::access_test {
namespace {

using namespace std::chrono_literals;

std::string base64(const std::string& text) {
  std::string out(4 * ((text.size() + 2) / 3) + 1, '\0');
  const int n = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()),
                                reinterpret_cast<const unsigned char*>(text.data()),
                                static_cast<int>(text.size()));
  out.resize(static_cast<std::size_t>(n));
  return out;
}

// A self-signed P-256 certificate for 127.0.0.1 (subjectAltName IP), written as PEM files.
struct TestCertificate {
  std::filesystem::path certificate;
  std::filesystem::path private_key;
};

TestCertificate make_certificate(const std::filesystem::path& dir) {
  EVP_PKEY* key = EVP_EC_gen("P-256");
  X509* cert = X509_new();
  ASN1_INTEGER_set(X509_get_serialNumber(cert), 1);
  X509_gmtime_adj(X509_getm_notBefore(cert), -60);
  X509_gmtime_adj(X509_getm_notAfter(cert), 3600);
  X509_set_pubkey(cert, key);
  X509_NAME* name = X509_get_subject_name(cert);
  X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC,
                             reinterpret_cast<const unsigned char*>("127.0.0.1"), -1, -1, 0);
  X509_set_issuer_name(cert, name);
  X509V3_CTX context;
  X509V3_set_ctx_nodb(&context);
  X509V3_set_ctx(&context, cert, cert, nullptr, nullptr, 0);
  X509_EXTENSION* san =
      X509V3_EXT_conf_nid(nullptr, &context, NID_subject_alt_name, "IP:127.0.0.1");
  X509_add_ext(cert, san, -1);
  X509_EXTENSION_free(san);
  X509_sign(cert, key, EVP_sha256());
  TestCertificate files{dir / "server.crt", dir / "server.key"};
  FILE* out = std::fopen(files.certificate.c_str(), "w");
  PEM_write_X509(out, cert);
  std::fclose(out);
  out = std::fopen(files.private_key.c_str(), "w");
  PEM_write_PrivateKey(out, key, nullptr, nullptr, 0, nullptr, nullptr);
  std::fclose(out);
  X509_free(cert);
  EVP_PKEY_free(key);
  return files;
}

class TempDir {
 public:
  TempDir() {
    char pattern[] = "/tmp/dronetrack-access-XXXXXX";
    path_ = ::mkdtemp(pattern);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

void write_text(const std::filesystem::path& file, const std::string& text) {
  std::ofstream(file) << text;
}

TEST(UserFile, VerifiesTheRightPasswordOnly) {
  const std::string line = make_user_line("alice", "correct horse", kMinimumPasswordIterations);
  const UserFile users = UserFile::parse(line + "\n# comment\n\n", "users");
  ASSERT_EQ(users.users().size(), 1U);
  EXPECT_TRUE(users.verify("alice", "correct horse"));
  EXPECT_FALSE(users.verify("alice", "correct horsE"));
  EXPECT_FALSE(users.verify("bob", "correct horse"));
  // A fresh salt every time: the same password never gives the same line.
  EXPECT_NE(line, make_user_line("alice", "correct horse", kMinimumPasswordIterations));
}

TEST(UserFile, NamesTheLineAndWhatIsWrong) {
  const std::string good = make_user_line("alice", "pw", kMinimumPasswordIterations);
  const auto error_of = [](const std::string& text) {
    try {
      UserFile::parse(text, "users.txt");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error_of("# c\nalice:pw\n"),
            "users.txt:2: expected name:pbkdf2-sha256:ITERATIONS:SALT_HEX:HASH_HEX (5 fields), "
            "got 2");
  EXPECT_EQ(error_of("alice:md5:100000:00112233445566:" + std::string(64, 'a')),
            "users.txt:1: unknown hash scheme 'md5'");
  EXPECT_EQ(error_of("alice:pbkdf2-sha256:1000:0011223344556677:" + std::string(64, 'a')),
            "users.txt:1: iterations 1000 below the minimum 100000");
  EXPECT_EQ(error_of("alice:pbkdf2-sha256:100000:0011223344556677:abc"),
            "users.txt:1: hash must be 32 bytes of hex");
  EXPECT_EQ(error_of("a b:pbkdf2-sha256:100000:0011223344556677:" + std::string(64, 'a')),
            "users.txt:1: user name must be 1-64 letters, digits, '.', '_' or '-'");
  EXPECT_EQ(error_of(good + "\n" + good), "users.txt:2: user 'alice' appears twice");
  EXPECT_THROW(make_user_line("alice", ""), std::runtime_error);
}

TEST(BasicAuthorization, ParsesOnlyWellFormedHeaders) {
  std::string user, password;
  ASSERT_TRUE(parse_basic_authorization("Basic " + base64("alice:a:b c"), user, password));
  EXPECT_EQ(user, "alice");
  EXPECT_EQ(password, "a:b c");  // the password may hold colons
  ASSERT_TRUE(parse_basic_authorization("basic " + base64("bob:x"), user, password));
  EXPECT_EQ(user, "bob");
  EXPECT_FALSE(parse_basic_authorization("Bearer abc", user, password));
  EXPECT_FALSE(parse_basic_authorization("Basic " + base64("nocolon"), user, password));
  EXPECT_FALSE(parse_basic_authorization("Basic !!!!", user, password));
  EXPECT_FALSE(parse_basic_authorization("Basic abc", user, password));  // not a multiple of 4
  EXPECT_FALSE(parse_basic_authorization("Basic ", user, password));
}

TEST(ClientAddress, GroupsIpv6By64AndKnowsLoopback) {
  EXPECT_EQ(client_address_key("192.0.2.7"), "192.0.2.7");
  EXPECT_EQ(client_address_key("::ffff:192.0.2.7"), "192.0.2.7");
  EXPECT_EQ(client_address_key("2001:db8:1:2:3:4:5:6"), "2001:db8:1:2::/64");
  EXPECT_TRUE(is_loopback_host("127.0.0.1"));
  EXPECT_TRUE(is_loopback_host("127.3.2.1"));
  EXPECT_TRUE(is_loopback_host("::1"));
  EXPECT_TRUE(is_loopback_host("localhost"));
  EXPECT_FALSE(is_loopback_host("0.0.0.0"));
  EXPECT_FALSE(is_loopback_host("::"));
  EXPECT_FALSE(is_loopback_host("192.168.1.10"));
  EXPECT_FALSE(is_loopback_host("gateway.local"));
}

TEST(ClientBudget, RateBurstThenRefill) {
  ConnectionLimits limits;
  limits.request_burst_per_client = 3;
  limits.requests_per_second_per_client = 2;
  ClientBudget budget(limits);
  const auto t0 = ClientBudget::Clock::now();
  double retry_s = 0.0;
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(budget.take_request("a", t0, retry_s)) << i;
  EXPECT_FALSE(budget.take_request("a", t0, retry_s));
  EXPECT_NEAR(retry_s, 0.5, 1e-9);                     // one token at 2 per second
  EXPECT_TRUE(budget.take_request("b", t0, retry_s));  // another client is not held up
  EXPECT_TRUE(budget.take_request("a", t0 + 500ms, retry_s));
  EXPECT_FALSE(budget.take_request("a", t0 + 500ms, retry_s));
}

TEST(ClientBudget, FailedLoginsBlockForTheRestOfTheWindow) {
  ConnectionLimits limits;
  limits.max_failed_logins_per_client = 3;
  limits.login_failure_window = 10s;
  ClientBudget budget(limits);
  const auto t0 = ClientBudget::Clock::now();
  double retry_s = 0.0;
  EXPECT_FALSE(budget.logins_blocked("a", t0, retry_s));
  for (int i = 0; i < 3; ++i) budget.login_failed("a", t0 + 1s);
  EXPECT_TRUE(budget.logins_blocked("a", t0 + 2s, retry_s));
  EXPECT_NEAR(retry_s, 8.0, 1e-6);
  EXPECT_FALSE(budget.logins_blocked("b", t0 + 2s, retry_s));
  EXPECT_FALSE(budget.logins_blocked("a", t0 + 11s, retry_s));
}

TEST(ClientBudget, StreamsPerClient) {
  ConnectionLimits limits;
  limits.max_streams_per_client = 2;
  ClientBudget budget(limits);
  EXPECT_TRUE(budget.open_stream("a"));
  EXPECT_TRUE(budget.open_stream("a"));
  EXPECT_FALSE(budget.open_stream("a"));
  EXPECT_TRUE(budget.open_stream("b"));
  budget.close_stream("a");
  EXPECT_TRUE(budget.open_stream("a"));
}

std::string start_error(HttpOptions options) {
  LiveState state(test::two_array_layout());
  HttpServer server(state, std::move(options));
  try {
    server.start();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "started";
}

TEST(HttpAccess, RefusesToServeBeyondLoopbackWithoutTlsAndUsers) {
  TempDir dir;
  const TestCertificate cert = make_certificate(dir.path());
  write_text(dir.path() / "users", make_user_line("op", "pw", kMinimumPasswordIterations) + "\n");
  HttpOptions options;
  options.bind = "0.0.0.0:0";
  EXPECT_EQ(start_error(options),
            "HTTP: refusing to serve on 0.0.0.0:0 (beyond loopback) without TLS "
            "(http.tls_certificate, http.tls_private_key) and users (http.users_file); see "
            "docs/http_api.md, \"Access\"");
  options.tls_certificate = cert.certificate;
  options.tls_private_key = cert.private_key;
  EXPECT_EQ(start_error(options),
            "HTTP: refusing to serve on 0.0.0.0:0 (beyond loopback) without users "
            "(http.users_file); see docs/http_api.md, \"Access\"");
  options.users_file = dir.path() / "users";
  EXPECT_EQ(start_error(options), "started");
  options.tls_private_key.clear();
  EXPECT_EQ(start_error(options),
            "HTTP: TLS needs both a certificate (http.tls_certificate) and its private key "
            "(http.tls_private_key)");
  // Loopback stays open without either, as before.
  HttpOptions local;
  local.bind = "127.0.0.1:0";
  EXPECT_EQ(start_error(local), "started");
}

TEST(HttpAccess, NamesTheUnusableFile) {
  TempDir dir;
  const TestCertificate cert = make_certificate(dir.path());
  write_text(dir.path() / "not-a-cert.pem", "hello\n");
  HttpOptions options;
  options.bind = "127.0.0.1:0";
  options.tls_certificate = dir.path() / "not-a-cert.pem";
  options.tls_private_key = cert.private_key;
  EXPECT_NE(
      start_error(options).find("TLS certificate " + (dir.path() / "not-a-cert.pem").string()),
      std::string::npos);
  options.tls_certificate = cert.certificate;
  write_text(dir.path() / "users", "op:pbkdf2-sha256:5:00:00\n");
  options.users_file = dir.path() / "users";
  EXPECT_EQ(start_error(options),
            (dir.path() / "users").string() + ":1: iterations 5 below the minimum 100000");
}

class HttpsServer : public ::testing::Test {
 protected:
  void SetUp() override {
    cert_ = make_certificate(dir_.path());
    users_file_ = dir_.path() / "users";
    write_text(users_file_,
               make_user_line("operator", "s3cret pass", kMinimumPasswordIterations) + "\n" +
                   make_user_line("viewer", "other", kMinimumPasswordIterations) + "\n");
  }
  void start(ConnectionLimits limits = {}) {
    HttpOptions options;
    options.bind = "127.0.0.1:0";
    options.tls_certificate = cert_.certificate;
    options.tls_private_key = cert_.private_key;
    options.users_file = users_file_;
    options.limits = limits;
    server_ = std::make_unique<HttpServer>(state_, options);
    server_->start();
  }
  std::unique_ptr<httplib::SSLClient> client() {
    auto c = std::make_unique<httplib::SSLClient>("127.0.0.1", server_->port());
    c->set_ca_cert_path(cert_.certificate.c_str());
    c->enable_server_certificate_verification(true);
    c->set_connection_timeout(2, 0);
    c->set_read_timeout(2, 0);
    return c;
  }

  TempDir dir_;
  TestCertificate cert_;
  std::filesystem::path users_file_;
  LiveState state_{test::two_array_layout()};
  std::unique_ptr<HttpServer> server_;
};

TEST_F(HttpsServer, ServesOnlyAuthenticatedUsersOverTls) {
  start();
  EXPECT_EQ(server_->url().rfind("https://127.0.0.1:", 0), 0U);
  auto c = client();
  auto anonymous = c->Get("/api/site");
  ASSERT_TRUE(anonymous) << httplib::to_string(anonymous.error());
  EXPECT_EQ(anonymous->status, 401);
  EXPECT_EQ(anonymous->get_header_value("WWW-Authenticate"),
            "Basic realm=\"dronetrack\", charset=\"UTF-8\"");
  c->set_basic_auth("operator", "wrong");
  auto wrong = c->Get("/api/site");
  ASSERT_TRUE(wrong);
  EXPECT_EQ(wrong->status, 401);
  c->set_basic_auth("operator", "s3cret pass");
  for (int i = 0; i < 3; ++i) {  // the second and third from the verified-password cache
    auto right = c->Get("/api/site");
    ASSERT_TRUE(right);
    EXPECT_EQ(right->status, 200);
    EXPECT_NE(right->body.find("\"arrays\""), std::string::npos);
  }
  // The page's files are behind the same door.
  c->set_basic_auth("", "");
  auto page = c->Get("/index.html");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 401);
}

TEST_F(HttpsServer, PlaintextClientsGetNothing) {
  start();
  httplib::Client plain("127.0.0.1", server_->port());
  plain.set_connection_timeout(1, 0);
  plain.set_read_timeout(1, 0);
  plain.set_basic_auth("operator", "s3cret pass");
  const auto result = plain.Get("/api/site");
  EXPECT_FALSE(result && result->status == 200);
}

TEST_F(HttpsServer, AStalledHandshakeIsCutAtTheHeadDeadline) {
  ConnectionLimits limits;
  limits.head_timeout = 300ms;
  start(limits);
  test::RawClient raw(server_->port());
  ASSERT_TRUE(raw.connected());
  const auto opened = test::RawClient::Clock::now();
  for (int i = 0; i < 40 && !raw.closed(); ++i) raw.pump(100ms);
  ASSERT_TRUE(raw.closed());
  EXPECT_LT(raw.closed_at() - opened, 2s);
  EXPECT_TRUE(raw.received().empty());  // no plaintext answer into a TLS port
}

TEST_F(HttpsServer, RevokedUserIsRefusedWithoutRestart) {
  start();
  auto c = client();
  c->set_basic_auth("viewer", "other");
  auto before = c->Get("/api/tracks");
  ASSERT_TRUE(before);
  EXPECT_EQ(before->status, 200);
  // Revoke: rewrite the file without the viewer (a different size, so no mtime race).
  write_text(users_file_,
             make_user_line("operator", "s3cret pass", kMinimumPasswordIterations) + "\n");
  std::this_thread::sleep_for(1100ms);  // the file is looked at most once a second
  auto after = c->Get("/api/tracks");
  ASSERT_TRUE(after);
  EXPECT_EQ(after->status, 401);
  c->set_basic_auth("operator", "s3cret pass");
  auto other = c->Get("/api/tracks");
  ASSERT_TRUE(other);
  EXPECT_EQ(other->status, 200);
}

TEST_F(HttpsServer, PasswordGuessingIsThrottled) {
  ConnectionLimits limits;
  limits.max_failed_logins_per_client = 3;
  start(limits);
  auto c = client();
  c->set_basic_auth("operator", "guess");
  for (int i = 0; i < 3; ++i) {
    auto r = c->Get("/api/site");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 401) << i;
  }
  // Blocked now, even with the right password, for the rest of the window.
  c->set_basic_auth("operator", "s3cret pass");
  auto blocked = c->Get("/api/site");
  ASSERT_TRUE(blocked);
  EXPECT_EQ(blocked->status, 429);
  EXPECT_FALSE(blocked->get_header_value("Retry-After").empty());
}

TEST(HttpLimits, RequestRateAndStreamsPerClient) {
  LiveState state(test::two_array_layout());
  HttpOptions options;
  options.bind = "127.0.0.1:0";
  options.limits.request_burst_per_client = 5;
  options.limits.requests_per_second_per_client = 0.5;
  options.limits.max_streams_per_client = 1;
  HttpServer server(state, options);
  server.start();
  // One stream from 127.0.0.2 is allowed, a second one gets 429.
  test::RawClient first(server.port(), "127.0.0.2");
  ASSERT_TRUE(first.send("GET /api/stream HTTP/1.1\r\nHost: x\r\n\r\n"));
  for (int i = 0; i < 20 && first.status() == 0; ++i) first.pump(50ms);
  EXPECT_EQ(first.status(), 200);
  test::RawClient second(server.port(), "127.0.0.2");
  ASSERT_TRUE(second.send("GET /api/stream HTTP/1.1\r\nHost: x\r\n\r\n"));
  for (int i = 0; i < 20 && second.status() == 0; ++i) second.pump(50ms);
  EXPECT_EQ(second.status(), 429);
  // 127.0.0.3 has spent nothing: 5 requests pass, the 6th is refused with Retry-After.
  int refused = 0;
  std::string retry_after;
  for (int i = 0; i < 6; ++i) {
    test::RawClient raw(server.port(), "127.0.0.3");
    ASSERT_TRUE(raw.send("GET /api/tracks HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"));
    for (int k = 0; k < 20 && !raw.closed(); ++k) raw.pump(50ms);
    if (raw.status() == 429) {
      ++refused;
      EXPECT_NE(raw.received().find("Retry-After: 2"), std::string::npos) << raw.received();
    } else {
      EXPECT_EQ(raw.status(), 200) << i;
    }
  }
  EXPECT_EQ(refused, 1);
  server.stop();
}

}  // namespace
}  // namespace dronetrack::http_api::access_test
