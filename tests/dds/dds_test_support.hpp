#pragma once
// Every DDS test runs on loopback only and on its own domain id, so parallel test processes
// (and anything else on the machine) never meet.
#include <cstdlib>
#include <string>

namespace dronetrack::dds::testing {

inline std::string loopback_uri() {
  return std::string("file://") + DRONETRACK_SOURCE_DIR + "/config/cyclonedds-loopback.xml";
}

// Call before the first participant of the process is created.
inline void use_loopback() { setenv("CYCLONEDDS_URI", loopback_uri().c_str(), 1); }

}  // namespace dronetrack::dds::testing
