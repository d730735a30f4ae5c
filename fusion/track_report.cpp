#include "fusion/track_report.hpp"

namespace dronetrack::fusion {

const char* to_string(TrackStatus status) {
  switch (status) {
    case TrackStatus::tentative:
      return "tentative";
    case TrackStatus::confirmed:
      return "confirmed";
    case TrackStatus::coasting:
      return "coasting";
  }
  return "unknown";
}

}  // namespace dronetrack::fusion
