#pragma once
// Every DDS test runs on loopback only and on its own domain id, so parallel test processes
// (and anything else on the machine) never meet.
#include <cstdlib>
#include <string>

namespace dronetrack::dds::testing {

// Built with append, not a chain of operator+ on temporaries: GCC 12 at -O3 misreads the
// latter, once inlined into a large test body, as a write past a short string (-Warray-bounds).
inline std::string loopback_uri() {
  std::string uri = "file://";
  uri.append(DRONETRACK_SOURCE_DIR);
  uri.append("/config/cyclonedds-loopback.xml");
  return uri;
}

// Call before the first participant of the process is created.
inline void use_loopback() { setenv("CYCLONEDDS_URI", loopback_uri().c_str(), 1); }

}  // namespace dronetrack::dds::testing
