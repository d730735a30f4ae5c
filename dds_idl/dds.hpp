#pragma once
// Small RAII wrappers over the Cyclone DDS 0.10 C API. Entities delete themselves; samples are
// taken on loan and the loan is returned when the Samples object goes out of scope. Every
// failing call throws DdsError naming the call and Cyclone's reason. See DDS_NOTES.md for the
// pitfalls these wrappers exist to avoid.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <dds/dds.h>

namespace dronetrack::dds {

class DdsError : public std::runtime_error {
 public:
  DdsError(const std::string& call, dds_return_t code);
  dds_return_t code() const { return code_; }

 private:
  dds_return_t code_;
};

// Throws DdsError if `code` is negative; returns it otherwise.
dds_return_t check(dds_return_t code, const char* call);

dds_duration_t to_dds(std::chrono::nanoseconds duration);

// A move-only owner of one DDS entity handle.
class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t handle) : handle_(handle) {}
  ~Entity() { reset(); }
  Entity(Entity&& other) noexcept : handle_(std::exchange(other.handle_, 0)) {}
  Entity& operator=(Entity&& other) noexcept {
    if (this != &other) {
      reset();
      handle_ = std::exchange(other.handle_, 0);
    }
    return *this;
  }
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;

  dds_entity_t handle() const { return handle_; }
  explicit operator bool() const { return handle_ > 0; }

 private:
  void reset() {
    if (handle_ > 0) dds_delete(handle_);
    handle_ = 0;
  }
  dds_entity_t handle_ = 0;
};

// QoS builder. Each setter returns *this so profiles read as one expression.
class Qos {
 public:
  Qos() : qos_(dds_create_qos()) {}
  ~Qos() {
    if (qos_) dds_delete_qos(qos_);
  }
  Qos(Qos&& other) noexcept : qos_(std::exchange(other.qos_, nullptr)) {}
  Qos& operator=(Qos&&) = delete;
  Qos(const Qos&) = delete;
  Qos& operator=(const Qos&) = delete;

  Qos& reliable(std::chrono::nanoseconds max_blocking = std::chrono::milliseconds(100)) {
    dds_qset_reliability(qos_, DDS_RELIABILITY_RELIABLE, to_dds(max_blocking));
    return *this;
  }
  Qos& best_effort() {
    dds_qset_reliability(qos_, DDS_RELIABILITY_BEST_EFFORT, 0);
    return *this;
  }
  Qos& keep_last(int depth) {
    dds_qset_history(qos_, DDS_HISTORY_KEEP_LAST, depth);
    return *this;
  }
  Qos& volatile_durability() {
    dds_qset_durability(qos_, DDS_DURABILITY_VOLATILE);
    return *this;
  }
  // Late joiners get the last `depth` samples per instance. The durability service history,
  // not the writer's history, decides how many (DDS_NOTES), so both are set.
  Qos& transient_local(int depth) {
    dds_qset_durability(qos_, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_qset_durability_service(qos_, 0, DDS_HISTORY_KEEP_LAST, depth, DDS_LENGTH_UNLIMITED,
                                DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
    return *this;
  }
  Qos& liveliness_automatic(std::chrono::nanoseconds lease) {
    dds_qset_liveliness(qos_, DDS_LIVELINESS_AUTOMATIC, to_dds(lease));
    return *this;
  }
  // false: a writer that vanishes leaves its instances NOT_ALIVE_NO_WRITERS (not disposed),
  // which is how a reader learns which key (array) went away.
  Qos& autodispose_unregistered(bool autodispose) {
    dds_qset_writer_data_lifecycle(qos_, autodispose);
    return *this;
  }
  // Publisher/subscriber partitions (wildcards '*' and '?' match on the reader side). The
  // secure site puts each array's Doa/NodeStatus/ArrayPose in partition "array.ID", which its
  // permissions grant only to that array's identity.
  Qos& partitions(const std::vector<std::string>& names) {
    std::vector<const char*> pointers;
    for (const std::string& name : names) pointers.push_back(name.c_str());
    dds_qset_partition(qos_, static_cast<uint32_t>(pointers.size()), pointers.data());
    return *this;
  }
  const dds_qos_t* get() const { return qos_; }

 private:
  dds_qos_t* qos_;
};

// The partition of one array's samples on a secure site.
inline std::string array_partition(const std::string& array_id) { return "array." + array_id; }

// DDS Security (the OMG builtin plugins Debian's Cyclone ships: authentication, access control,
// cryptography) for one participant: its identity and the site's signed documents, as made by
// scripts/site-pki.sh. docs/deployment.md, "DDS Security".
struct SecurityFiles {
  std::filesystem::path identity_ca;           // PEM: the CA that signed every identity
  std::filesystem::path identity_certificate;  // PEM: this participant's certificate
  std::filesystem::path private_key;           // PEM: its key
  std::filesystem::path permissions_ca;        // PEM: the CA that signed the documents below
  std::filesystem::path governance;            // S/MIME-signed governance document (.p7s)
  std::filesystem::path permissions;           // S/MIME-signed permissions of this identity
};

// Where Debian's Cyclone keeps the plugins (not on the loader's default path).
std::string security_plugin_directory();

class Participant {
 public:
  // The domain's network settings come from CYCLONEDDS_URI (config/cyclonedds-*.xml). With
  // `security`, the participant authenticates with that identity and only talks to peers the
  // site CA vouches for, within the permissions signed for it; a file that is missing or does
  // not verify makes the constructor throw naming it.
  explicit Participant(dds_domainid_t domain, const SecurityFiles* security = nullptr);
  dds_entity_t handle() const { return entity_.handle(); }
  dds_domainid_t domain() const { return domain_; }

 private:
  Entity entity_;
  dds_domainid_t domain_;
};

// Each IDL type registers its descriptor and topic name (topics.hpp).
template <class T>
struct TopicTraits;

template <class T>
class Topic {
 public:
  explicit Topic(const Participant& participant)
      : entity_(check(dds_create_topic(participant.handle(), TopicTraits<T>::descriptor(),
                                       TopicTraits<T>::name(), nullptr, nullptr),
                      "dds_create_topic")) {}
  dds_entity_t handle() const { return entity_.handle(); }

 private:
  Entity entity_;
};

template <class T>
class Writer {
 public:
  Writer(const Participant& participant, const Topic<T>& topic, const Qos& qos)
      : entity_(check(dds_create_writer(participant.handle(), topic.handle(), qos.get(), nullptr),
                      "dds_create_writer")) {}
  // Copies synchronously: `sample` may point into caller-owned strings and vectors.
  void write(const T& sample) const { check(dds_write(entity_.handle(), &sample), "dds_write"); }
  // Same, but returns Cyclone's code instead of throwing (e.g. BAD_PARAMETER for an oversize
  // sequence) for callers that count failures.
  dds_return_t try_write(const T& sample) const { return dds_write(entity_.handle(), &sample); }
  // Only the key fields of `key_sample` matter.
  void dispose(const T& key_sample) const {
    check(dds_dispose(entity_.handle(), &key_sample), "dds_dispose");
  }
  void unregister(const T& key_sample) const {
    check(dds_unregister_instance(entity_.handle(), &key_sample), "dds_unregister_instance");
  }
  std::uint32_t matched_readers() const {
    dds_publication_matched_status_t status{};
    check(dds_get_publication_matched_status(entity_.handle(), &status),
          "dds_get_publication_matched_status");
    return status.current_count;
  }
  // Polls until at least `count` readers matched or the timeout passed.
  bool wait_for_readers(std::uint32_t count, std::chrono::nanoseconds timeout) const;
  // Blocks until every matched reliable reader acknowledged what was written.
  bool wait_for_acks(std::chrono::nanoseconds timeout) const {
    return dds_wait_for_acks(entity_.handle(), to_dds(timeout)) == DDS_RETCODE_OK;
  }
  dds_entity_t handle() const { return entity_.handle(); }

 private:
  Entity entity_;
};

template <class T>
bool Writer<T>::wait_for_readers(std::uint32_t count, std::chrono::nanoseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (matched_readers() < count) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    dds_sleepfor(DDS_MSECS(5));
  }
  return true;
}

// Up to kMaxSamples samples on loan from a reader; the loan is returned in the destructor.
// Neither copyable nor movable: use it in the scope that took it and copy out what you keep.
// Any other loaned read on such a reader needs room for kMaxSamples buffer pointers: Cyclone 0.10
// hands out the reader's cached loan by filling as many pointers as it holds, whatever `bufsz`
// says (a one-pointer array in a test had 63 written past it; docs/ci.md).
template <class T>
class Samples {
 public:
  static constexpr int kMaxSamples = 64;

  explicit Samples(dds_entity_t reader) : reader_(reader) {
    buffers_[0] = nullptr;  // null first buffer: Cyclone lends its own memory
    count_ = dds_take(reader_, buffers_, infos_, kMaxSamples, kMaxSamples);
    if (count_ < 0) {
      const dds_return_t code = count_;
      count_ = 0;
      throw DdsError("dds_take", code);
    }
  }
  ~Samples() {
    if (count_ > 0) dds_return_loan(reader_, buffers_, count_);
  }
  Samples(const Samples&) = delete;
  Samples& operator=(const Samples&) = delete;

  std::size_t size() const { return static_cast<std::size_t>(count_); }
  bool empty() const { return count_ == 0; }
  // Only key fields are meaningful when !info(i).valid_data (an instance state change).
  const T& data(std::size_t i) const { return *static_cast<const T*>(buffers_[i]); }
  const dds_sample_info_t& info(std::size_t i) const { return infos_[i]; }

 private:
  dds_entity_t reader_;
  void* buffers_[kMaxSamples];
  dds_sample_info_t infos_[kMaxSamples];
  dds_return_t count_ = 0;
};

// A reader with its own ReadCondition on not-yet-read samples (DATA_AVAILABLE is reset by every
// take and can strand the tail of a burst; a ReadCondition cannot) and a waitset to block on.
template <class T>
class Reader {
 public:
  // `status_mask` (e.g. DDS_LIVELINESS_CHANGED_STATUS) enables communication statuses on the
  // reader's status condition; each enabled status must then be read with its getter.
  Reader(const Participant& participant, const Topic<T>& topic, const Qos& qos,
         std::uint32_t status_mask = 0)
      : entity_(check(dds_create_reader(participant.handle(), topic.handle(), qos.get(), nullptr),
                      "dds_create_reader")),
        condition_(check(dds_create_readcondition(entity_.handle(), DDS_NOT_READ_SAMPLE_STATE |
                                                                        DDS_ANY_VIEW_STATE |
                                                                        DDS_ANY_INSTANCE_STATE),
                         "dds_create_readcondition")),
        waitset_(check(dds_create_waitset(participant.handle()), "dds_create_waitset")) {
    check(dds_set_status_mask(entity_.handle(), status_mask), "dds_set_status_mask");
    check(dds_waitset_attach(waitset_.handle(), condition_.handle(), 0), "dds_waitset_attach");
  }
  // Takes what is there now (up to Samples::kMaxSamples); take again until empty.
  Samples<T> take() const { return Samples<T>(entity_.handle()); }
  // Blocks until unread samples are present or the timeout passes. True if samples are there.
  bool wait(std::chrono::nanoseconds timeout) const {
    const dds_return_t triggered = dds_waitset_wait(waitset_.handle(), nullptr, 0, to_dds(timeout));
    check(triggered, "dds_waitset_wait");
    return triggered > 0;
  }
  std::uint32_t matched_writers() const {
    dds_subscription_matched_status_t status{};
    check(dds_get_subscription_matched_status(entity_.handle(), &status),
          "dds_get_subscription_matched_status");
    return status.current_count;
  }
  bool wait_for_writers(std::uint32_t count, std::chrono::nanoseconds timeout) const {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (matched_writers() < count) {
      if (std::chrono::steady_clock::now() >= deadline) return false;
      dds_sleepfor(DDS_MSECS(5));
    }
    return true;
  }
  // Reads (and so resets) the liveliness status; enable it in the status mask to block on it.
  dds_liveliness_changed_status_t liveliness() const {
    dds_liveliness_changed_status_t status{};
    check(dds_get_liveliness_changed_status(entity_.handle(), &status),
          "dds_get_liveliness_changed_status");
    return status;
  }
  dds_entity_t handle() const { return entity_.handle(); }
  dds_entity_t read_condition() const { return condition_.handle(); }

 private:
  Entity entity_;
  Entity condition_;
  Entity waitset_;
};

// One waitset over several readers' conditions (the fusion waits on Doa and NodeStatus at once).
class WaitSet {
 public:
  explicit WaitSet(const Participant& participant)
      : entity_(check(dds_create_waitset(participant.handle()), "dds_create_waitset")) {}
  // `condition`: a ReadCondition, or a reader itself to wake on its enabled statuses.
  void attach(dds_entity_t condition) {
    check(dds_waitset_attach(entity_.handle(), condition, 0), "dds_waitset_attach");
  }
  // Number of triggered conditions (0 on timeout).
  int wait(std::chrono::nanoseconds timeout) const {
    return check(dds_waitset_wait(entity_.handle(), nullptr, 0, to_dds(timeout)),
                 "dds_waitset_wait");
  }
  // Wakes a wait() from another thread or a signal handler's helper thread.
  void wake() const { dds_waitset_set_trigger(entity_.handle(), true); }
  void clear_wake() const { dds_waitset_set_trigger(entity_.handle(), false); }

 private:
  Entity entity_;
};

}  // namespace dronetrack::dds
