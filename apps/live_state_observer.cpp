#include "apps/live_state_observer.hpp"

#include "apps/commands.hpp"
#include "apps/data_paths.hpp"
#include "common/log.hpp"

#include <cstdlib>
#include <system_error>

namespace dronetrack::apps {

std::filesystem::path default_web_root() {
  if (const char* root = std::getenv("DRONETRACK_WEB_ROOT")) return root;
  return data_path("web", "web");
}

http_api::HttpOptions http_options_for(const config::SiteConfig& site, const std::string& bind,
                                       const std::filesystem::path& web_root,
                                       const std::string& option) {
  http_api::HttpOptions options;
  options.bind = bind;
  options.web_root = web_root.empty() ? default_web_root() : web_root;
  options.tls_certificate = site.http.tls_certificate;
  options.tls_private_key = site.http.tls_private_key;
  options.users_file = site.http.users_file;
  if (const std::string problem = http_api::exposure_problem(options); !problem.empty()) {
    throw ArgumentError(option + " " + bind + ": " + problem);
  }
  // The API still works without the page; say why the browser will get 404s.
  std::error_code error;
  if (!std::filesystem::is_regular_file(options.web_root / "index.html", error)) {
    log::warn(
        "--http: no web page at ", options.web_root.string(),
        " (no index.html); serving the JSON API only (--web-root DIR or DRONETRACK_WEB_ROOT)");
  }
  return options;
}

}  // namespace dronetrack::apps
