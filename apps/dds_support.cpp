#include "apps/dds_support.hpp"

#include "apps/commands.hpp"
#include "common/log.hpp"

namespace dronetrack::apps {

int resolve_domain(const config::SiteConfig& site, std::optional<int> flag) {
  const int domain = flag.value_or(site.dds.domain_id);
  // Cyclone maps domain ids to UDP ports; above 232 the ports overflow (DDS_NOTES).
  if (domain < 0 || domain > 232) {
    throw UserError("DDS domain id " + std::to_string(domain) + " is outside 0..232");
  }
  return domain;
}

std::optional<dds::SecurityFiles> security_files(const config::SiteConfig& site,
                                                 const std::string& name) {
  if (!site.dds.secure()) return std::nullopt;
  const std::filesystem::path& dir = site.dds.security_directory;
  dds::SecurityFiles files;
  files.identity_ca = dir / "ca.crt";
  files.permissions_ca = dir / "ca.crt";
  files.governance = dir / "governance.p7s";
  files.identity_certificate = dir / (name + ".crt");
  files.private_key = dir / (name + ".key");
  files.permissions = dir / (name + "-permissions.p7s");
  for (const auto& file : {files.identity_ca, files.governance, files.identity_certificate,
                           files.private_key, files.permissions}) {
    std::error_code error;
    if (!std::filesystem::is_regular_file(file, error)) {
      throw UserError("DDS security: " + file.string() + " not found (identity '" + name +
                      "'; make it with scripts/site-pki.sh)");
    }
  }
  return files;
}

std::vector<std::string> array_ids(const config::SiteConfig& site) {
  std::vector<std::string> ids;
  ids.reserve(site.arrays.size());
  for (const auto& array : site.arrays) ids.push_back(array.geometry.id);
  return ids;
}

void ThrottledWarnings::count(int kind, const char* what) {
  if (kind < 0 || kind >= kKinds) return;
  Kind& entry = kinds_[static_cast<std::size_t>(kind)];
  entry.what = what;
  ++entry.pending;
  const auto now = std::chrono::steady_clock::now();
  if (now - entry.last_line >= std::chrono::seconds(1)) emit(entry, now);
}

void ThrottledWarnings::flush() {
  const auto now = std::chrono::steady_clock::now();
  for (Kind& entry : kinds_) {
    if (entry.pending > 0) emit(entry, now);
  }
}

void ThrottledWarnings::emit(Kind& kind, std::chrono::steady_clock::time_point now) {
  log::warn(kind.what, ": ", kind.pending, kind.pending == 1 ? " sample" : " samples", " ignored");
  kind.pending = 0;
  kind.last_line = now;
}

}  // namespace dronetrack::apps
