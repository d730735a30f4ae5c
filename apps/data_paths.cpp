#include "apps/data_paths.hpp"

#include <system_error>

namespace dronetrack::apps {

std::filesystem::path installed_data_dir() {
  std::error_code error;
  // The executable's real path (symlinks resolved), so a link in another bin/ still finds its
  // own prefix's files.
  const std::filesystem::path executable = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error || !executable.has_parent_path()) return {};
  return executable.parent_path().parent_path() / "share" / "dronetrack";
}

std::filesystem::path data_path(std::string_view installed, std::string_view in_source) {
  std::error_code error;
  if (const auto prefix = installed_data_dir(); !prefix.empty()) {
    const auto candidate = prefix / installed;
    if (std::filesystem::exists(candidate, error)) return candidate;
  }
  return std::filesystem::path(DRONETRACK_SOURCE_DIR) / in_source;
}

}  // namespace dronetrack::apps
