#include "dds_idl/dds.hpp"

#include "dds_idl/topics.hpp"

#include <memory>

namespace dronetrack::dds {

DdsError::DdsError(const std::string& call, dds_return_t code)
    : std::runtime_error(call + " failed: " + dds_strretcode(code)), code_(code) {}

dds_return_t check(dds_return_t code, const char* call) {
  if (code < 0) throw DdsError(call, code);
  return code;
}

dds_duration_t to_dds(std::chrono::nanoseconds duration) {
  return static_cast<dds_duration_t>(duration.count());
}

std::string security_plugin_directory() { return DRONETRACK_DDS_SECURITY_PLUGIN_DIR; }

namespace {

std::string file_uri(const std::filesystem::path& file, const char* what) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(file, error)) {
    throw std::runtime_error("DDS security: " + std::string(what) + " " + file.string() +
                             " is not a readable file");
  }
  return "file:" + std::filesystem::absolute(file).string();
}

dds_entity_t create_participant(dds_domainid_t domain, const SecurityFiles* security) {
  if (security == nullptr) {
    return check(dds_create_participant(domain, nullptr, nullptr), "dds_create_participant");
  }
  struct QosDeleter {
    void operator()(dds_qos_t* qos) const { dds_delete_qos(qos); }
  };
  std::unique_ptr<dds_qos_t, QosDeleter> qos(dds_create_qos());
  const std::string plugins = security_plugin_directory() + "/";
  const auto property = [&qos](const char* name, const std::string& value) {
    dds_qset_prop(qos.get(), name, value.c_str());
  };
  property("dds.sec.auth.library.path", plugins + "libdds_security_auth.so");
  property("dds.sec.auth.library.init", "init_authentication");
  property("dds.sec.auth.library.finalize", "finalize_authentication");
  property("dds.sec.auth.identity_ca", file_uri(security->identity_ca, "identity CA"));
  property("dds.sec.auth.identity_certificate",
           file_uri(security->identity_certificate, "identity certificate"));
  property("dds.sec.auth.private_key", file_uri(security->private_key, "private key"));
  property("dds.sec.access.library.path", plugins + "libdds_security_ac.so");
  property("dds.sec.access.library.init", "init_access_control");
  property("dds.sec.access.library.finalize", "finalize_access_control");
  property("dds.sec.access.permissions_ca", file_uri(security->permissions_ca, "permissions CA"));
  property("dds.sec.access.governance", file_uri(security->governance, "governance"));
  property("dds.sec.access.permissions", file_uri(security->permissions, "permissions"));
  property("dds.sec.crypto.library.path", plugins + "libdds_security_crypto.so");
  property("dds.sec.crypto.library.init", "init_crypto");
  property("dds.sec.crypto.library.finalize", "finalize_crypto");
  const dds_entity_t participant = dds_create_participant(domain, qos.get(), nullptr);
  if (participant < 0) {
    throw DdsError("dds_create_participant with DDS security (identity " +
                       security->identity_certificate.string() +
                       "; a certificate not signed by the identity CA, a key that does not "
                       "match, or documents not signed by the permissions CA are refused)",
                   participant);
  }
  return participant;
}

}  // namespace

Participant::Participant(dds_domainid_t domain, const SecurityFiles* security)
    : entity_(create_participant(domain, security)), domain_(domain) {}

namespace {

// Every writer: AUTOMATIC liveliness with a short lease, and instances that merely lose their
// writer stay NOT_ALIVE_NO_WRITERS instead of being disposed (DDS_NOTES: that is how the
// fusion tells which array died, and a reader DEADLINE is avoided because of the 0.10.2 bug).
void common_writer(Qos& qos) {
  qos.reliable().liveliness_automatic(kWriterLease).autodispose_unregistered(false);
}

}  // namespace

void doa_writer_qos(Qos& qos) {
  common_writer(qos);
  qos.keep_last(64).volatile_durability();
}
void doa_reader_qos(Qos& qos) {
  qos.reliable().keep_last(64).volatile_durability().liveliness_automatic(kWriterLease);
}
void status_writer_qos(Qos& qos) {
  common_writer(qos);
  qos.keep_last(1).transient_local(1);
}
void status_reader_qos(Qos& qos) {
  qos.reliable().keep_last(1).transient_local(1).liveliness_automatic(kWriterLease);
}
void track_writer_qos(Qos& qos) {
  common_writer(qos);
  qos.keep_last(1).transient_local(1);
}
void track_reader_qos(Qos& qos) {
  // Keep-last 4 per track: a reader that falls briefly behind still sees the newest state.
  qos.reliable().keep_last(4).transient_local(1).liveliness_automatic(kWriterLease);
}
void alert_writer_qos(Qos& qos) {
  common_writer(qos);
  qos.keep_last(16).volatile_durability();
}
void alert_reader_qos(Qos& qos) {
  qos.reliable().keep_last(16).volatile_durability().liveliness_automatic(kWriterLease);
}
void pose_writer_qos(Qos& qos) {
  common_writer(qos);
  qos.keep_last(32).volatile_durability();
}
void pose_reader_qos(Qos& qos) {
  qos.reliable().keep_last(32).volatile_durability().liveliness_automatic(kWriterLease);
}

}  // namespace dronetrack::dds
