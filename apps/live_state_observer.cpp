#include "apps/live_state_observer.hpp"

#include <cstdlib>

namespace dronetrack::apps {

std::filesystem::path default_web_root() {
  if (const char* root = std::getenv("DRONETRACK_WEB_ROOT")) return root;
  return DRONETRACK_WEB_ROOT;
}

}  // namespace dronetrack::apps
