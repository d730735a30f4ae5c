#include "dds_idl/dds.hpp"

#include "dds_idl/topics.hpp"

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

Participant::Participant(dds_domainid_t domain)
    : entity_(check(dds_create_participant(domain, nullptr, nullptr), "dds_create_participant")),
      domain_(domain) {}

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
