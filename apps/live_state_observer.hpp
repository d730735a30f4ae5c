#pragma once
// Feeds the HTTP API's live state from the fusion's outputs (replay, demo and DDS fusion).
#include <filesystem>

#include "apps/fusion_observer.hpp"
#include "config/site_config.hpp"
#include "http_api/http_server.hpp"
#include "http_api/live_state.hpp"

namespace dronetrack::apps {

class LiveStateObserver : public FusionObserver {
 public:
  explicit LiveStateObserver(http_api::LiveState& state) : state_(state) {}
  void on_doa(const doa::DoaMeasurement& doa) override { state_.publish_doa(doa); }
  void on_node_status(const doa::NodeStatus& status) override { state_.publish_node(status); }
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) override {
    state_.publish_tracks(time_s, tracks);
  }
  void on_zone_event(const fusion::ZoneEvent& event) override { state_.publish_alert(event); }
  void on_time(double time_s) override { state_.set_time(time_s); }

 private:
  http_api::LiveState& state_;
};

// The page's files: $DRONETRACK_WEB_ROOT, else PREFIX/share/dronetrack/web beside the installed
// executable, else the source tree's web/ this binary was built from (data_paths.hpp).
std::filesystem::path default_web_root();

// The server's options for serving `site` on `bind`: its TLS files and users file, the page
// from `web_root` (empty: default_web_root()).
// `option` names the command-line option in the refusal line.
http_api::HttpOptions http_options_for(const config::SiteConfig& site, const std::string& bind,
                                       const std::filesystem::path& web_root = {},
                                       const std::string& option = "--http");

}  // namespace dronetrack::apps
