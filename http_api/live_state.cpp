#include "http_api/live_state.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include <nlohmann/json.hpp>

#include "doa/array_geometry.hpp"

namespace dronetrack::http_api {
namespace {

using nlohmann::json;

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

json vec3(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

// Compass heading: clockwise from north (+y), degrees in [0, 360).
double compass_heading_deg(const Eigen::Vector3d& velocity_mps) {
  double heading = std::atan2(velocity_mps.x(), velocity_mps.y()) * kRadToDeg;
  if (heading < 0.0) heading += 360.0;
  return heading >= 360.0 ? 0.0 : heading;
}

json track_json(const fusion::TrackReport& track, const SiteLayout& layout) {
  json contributing = json::array();
  for (std::size_t i = 0; i < layout.arrays.size() && i < 64; ++i) {
    if ((track.contributing_arrays >> i) & 1u) contributing.push_back(layout.arrays[i].id);
  }
  const auto& c = track.covariance;
  return json{
      {"t", track.time_s},
      {"id", track.id},
      {"position_m", vec3(track.position_m)},
      {"velocity_mps", vec3(track.velocity_mps)},
      {"acceleration_mps2", vec3(track.acceleration_mps2)},
      {"position_std_m", vec3(track.position_std_m())},
      {"status", fusion::to_string(track.status)},
      {"class", fusion::to_string(track.track_class)},
      {"class_confidence", track.class_confidence},
      {"covariance_xy_m2",
       json::array({json::array({c(0, 0), c(0, 1)}), json::array({c(1, 0), c(1, 1)})})},
      {"contributing_arrays", std::move(contributing)},
      {"one_array", track.one_array},
      {"hypotheses", track.hypotheses},
      {"speed_mps", track.velocity_mps.norm()},
      {"ground_speed_mps", track.velocity_mps.head<2>().norm()},
      {"heading_deg", compass_heading_deg(track.velocity_mps)},
      {"last_update_s", track.last_update_s},
  };
}

json pose_json(double time_s, const doa::PoseStamp& pose) {
  return json{{"t", time_s},
              {"centre_m", vec3(pose.centre_m)},
              {"attitude_deg", vec3(doa::attitude_deg_of(pose.array_to_site))}};
}

// What a moving or rank-deficient array measured, as on the DOA line (docs/contract.md).
void add_doa_geometry(const doa::DoaMeasurement& doa, json& out) {
  if (doa.pose.moving) out["pose"] = pose_json(doa.time_s, doa.pose);
  if (doa.ambiguity == doa::DoaAmbiguity::cone) {
    out["cone"] =
        json{{"axis", vec3(doa.ambiguity_axis)},
             {"angle_deg", doa.cone_angle_rad * kRadToDeg},
             {"angle_std_deg", std::sqrt(std::max(0.0, doa.cone_angle_variance_rad2)) * kRadToDeg}};
  } else if (doa.ambiguity == doa::DoaAmbiguity::mirror_up_down) {
    out["mirror_normal"] = vec3(doa.ambiguity_axis);
  }
}

json doa_json(const doa::DoaMeasurement& doa) {
  const double az_std = std::sqrt(std::max(0.0, doa.azel_covariance_rad2(0, 0))) * kRadToDeg;
  const double el_std = std::sqrt(std::max(0.0, doa.azel_covariance_rad2(1, 1))) * kRadToDeg;
  json out{
      {"t", doa.time_s},
      {"array", doa.array_id},
      {"array_index", doa.array_index},
      {"source_index", doa.source_index},
      {"direction", vec3(doa.direction)},
      {"azimuth_deg", doa::azimuth_deg(doa.direction)},
      {"elevation_deg", doa::elevation_deg(doa.direction)},
      {"azel_std_deg", json::array({az_std, el_std})},
      {"quality", doa.quality},
      {"snr_db", doa.snr_db},
      {"ambiguity", doa::to_string(doa.ambiguity)},
  };
  add_doa_geometry(doa, out);
  return out;
}

// Problem flags as names, the channel's own audio first ("non_finite", "silent", ...), then
// how it compares with the array's other channels ("level_imbalance", "dead", ...), in bit order.
json problem_names(doa::HealthFlags flags, doa::ArrayFlags array_flags) {
  json names = json::array();
  for (int p = 0; p < doa::kHealthProblemCount; ++p) {
    const auto problem = static_cast<doa::HealthProblem>(p);
    if (doa::has_problem(flags, problem)) names.push_back(doa::to_string(problem));
  }
  for (int p = 0; p < doa::kArrayProblemCount; ++p) {
    const auto problem = static_cast<doa::ArrayProblem>(p);
    if (doa::has_problem(array_flags, problem)) names.push_back(doa::to_string(problem));
  }
  return names;
}

json status_json(const doa::NodeStatus& s) {
  json channels = json::array();
  for (const doa::ChannelStatus& channel : s.channels) {
    channels.push_back(json{
        {"problems", problem_names(channel.problems, channel.array_problems)},
        {"problems_seen", problem_names(channel.problems_seen, channel.array_problems_seen)},
        {"non_finite_samples", channel.non_finite_samples},
        {"clipped_samples", channel.clipped_samples},
        {"rms_dbfs", channel.rms_dbfs},
        {"level_offset_db", channel.level_offset_db},
        {"delay_offset_us", channel.delay_offset_us},
        // null until the delay is judged (node_status.hpp).
        {"delay_std_us", channel.delay_std_us < doa::kMaxHealthDelay_us ? json(channel.delay_std_us)
                                                                        : json(nullptr)},
    });
  }
  return json{
      {"t", s.time_s},
      {"alive", s.alive},
      {"sample_rate_hz", s.sample_rate_hz},
      {"overruns", s.overruns},
      {"dropouts", s.dropouts},
      {"clipped_samples", s.clipped_samples},
      {"non_finite_samples", s.non_finite_samples},
      {"level_dbfs", s.level_dbfs},
      {"noise_floor_dbfs", s.noise_floor_dbfs},
      {"snr_db", s.snr_db},
      {"detecting", s.detecting},
      {"closure_residual_us", s.closure_residual_us},
      {"fit_residual_us", s.fit_residual_us},
      {"software_version", s.software_version},
      {"incident_clips", s.incident_clips},
      {"incident_write_errors", s.incident_write_errors},
      {"channels", std::move(channels)},
  };
}

json alert_json(const fusion::ZoneEvent& e) {
  json alert{
      {"t", e.time_s},
      {"zone", e.zone},
      {"track_id", e.track_id},
      {"entered", e.entered},
      {"event", fusion::to_string(fusion::kind_of(e))},
      {"class", fusion::to_string(e.track_class)},
      {"position_m", vec3(e.position_m)},
  };
  if (e.kind == fusion::ZoneEventKind::class_changed)
    alert["previous_class"] = fusion::to_string(e.previous_class);
  return alert;
}

// nlohmann throws on invalid UTF-8 (an array id from a config file could carry some); replace
// rather than fail the whole document.
std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

struct HistoryPoint {
  double time_s;
  Eigen::Vector3d position_m;
};

}  // namespace

std::string sse_event(const std::string& name, const std::string& data) {
  std::string out;
  out.reserve(name.size() + data.size() + 16);
  out += "event: ";
  out += name;
  out += "\ndata: ";
  out += data;
  out += "\n\n";
  return out;
}

bool EventQueue::push(std::shared_ptr<const std::string> event) {
  bool dropped_now = false;
  {
    std::lock_guard lock(mutex_);
    if (dropped_ || closed_) return false;
    if (events_.size() >= capacity_) {
      dropped_ = dropped_now = true;
      events_.clear();  // nothing more will be sent to this client
    } else {
      events_.push_back(std::move(event));
    }
  }
  // No wake-up for an ordinary event: the reader polls (pop_all), so a publish costs no
  // context switch per client. A drop is signalled so the connection ends at once.
  if (dropped_now) ready_.notify_all();
  return true;
}

bool EventQueue::pop_all(std::vector<std::shared_ptr<const std::string>>& out, int timeout_ms) {
  std::unique_lock lock(mutex_);
  if (events_.empty() && !dropped_ && !closed_) {
    ready_.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                    [&] { return dropped_ || closed_; });
  }
  if (dropped_ || closed_) return false;
  for (auto& event : events_) out.push_back(std::move(event));
  events_.clear();
  return true;
}

void EventQueue::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  ready_.notify_all();
}

bool EventQueue::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

struct LiveState::State {
  double time_s = -std::numeric_limits<double>::infinity();
  double tracks_time_s = 0.0;
  std::vector<fusion::TrackReport> tracks;
  std::map<int, std::deque<HistoryPoint>> history;                  // by track id
  std::map<std::string, doa::NodeStatus> nodes;                     // by array id
  std::map<std::pair<std::string, int>, doa::DoaMeasurement> doas;  // (array, source_index)
  std::deque<fusion::ZoneEvent> alerts;
  // Moving arrays (issue 15): the latest pose stamp and the path so far, by array id.
  struct PathPoint {
    double time_s = 0.0;
    Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();
  };
  std::map<std::string, std::pair<double, doa::PoseStamp>> poses;
  std::map<std::string, std::deque<PathPoint>> paths;

  void advance(double t) {
    if (std::isfinite(t)) time_s = std::max(time_s, t);
  }
  double now() const { return std::isfinite(time_s) ? time_s : 0.0; }
};

LiveState::LiveState(SiteLayout layout, LiveStateLimits limits)
    : layout_(std::move(layout)), limits_(limits), state_(std::make_unique<State>()) {}

LiveState::~LiveState() {
  std::lock_guard lock(subscribers_mutex_);
  for (auto& queue : subscribers_) queue->close();
}

void LiveState::publish_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) {
  {
    std::lock_guard lock(mutex_);
    State& s = *state_;
    s.advance(time_s);
    s.tracks_time_s = time_s;
    s.tracks = tracks;
    for (const auto& track : tracks) {
      auto& points = s.history[track.id];
      points.push_back({time_s, track.position_m});
      while (points.size() > limits_.history_points_per_track) points.pop_front();
    }
    // Age out old points and forget tracks whose whole history is old.
    const double horizon = s.now() - limits_.history_window_s;
    for (auto it = s.history.begin(); it != s.history.end();) {
      auto& points = it->second;
      while (!points.empty() && points.front().time_s < horizon) points.pop_front();
      it = points.empty() ? s.history.erase(it) : std::next(it);
    }
  }
  if (subscriber_count() > 0) broadcast("tracks", tracks_json());
}

void LiveState::publish_doa(const doa::DoaMeasurement& doa) {
  {
    std::lock_guard lock(mutex_);
    state_->advance(doa.time_s);
    state_->doas[{doa.array_id, doa.source_index}] = doa;
    if (doa.pose.moving) record_pose(doa);
  }
  if (subscriber_count() > 0) broadcast("doa", dump(doa_json(doa)));
}

void LiveState::record_pose(const doa::DoaMeasurement& doa) {
  State& s = *state_;
  auto& latest = s.poses[doa.array_id];
  if (doa.time_s >= latest.first) latest = {doa.time_s, doa.pose};
  // A point per path_point_spacing_m moved or path_point_interval_s, bounded and aged like the
  // track history: the page draws the path, not every frame's pose.
  auto& path = s.paths[doa.array_id];
  const bool due =
      path.empty() ||
      (doa.time_s > path.back().time_s &&
       ((doa.pose.centre_m - path.back().centre_m).norm() >= limits_.path_point_spacing_m ||
        doa.time_s - path.back().time_s >= limits_.path_point_interval_s));
  if (due) path.push_back({doa.time_s, doa.pose.centre_m});
  while (path.size() > limits_.path_points_per_array) path.pop_front();
  const double horizon = s.now() - limits_.history_window_s;
  while (!path.empty() && path.front().time_s < horizon) path.pop_front();
}

void LiveState::publish_node(const doa::NodeStatus& status) {
  {
    std::lock_guard lock(mutex_);
    state_->advance(status.time_s);
    state_->nodes[status.array_id] = status;
  }
  if (subscriber_count() > 0) broadcast("nodes", nodes_json());
}

void LiveState::publish_alert(const fusion::ZoneEvent& event) {
  {
    std::lock_guard lock(mutex_);
    state_->advance(event.time_s);
    state_->alerts.push_back(event);
    while (state_->alerts.size() > limits_.max_alerts) state_->alerts.pop_front();
  }
  if (subscriber_count() > 0) broadcast("alert", dump(alert_json(event)));
}

void LiveState::set_time(double time_s) {
  std::lock_guard lock(mutex_);
  state_->advance(time_s);
}

double LiveState::time_s() const {
  std::lock_guard lock(mutex_);
  return state_->now();
}

std::string LiveState::site_json() const {
  json arrays = json::array();
  for (std::size_t i = 0; i < layout_.arrays.size(); ++i) {
    const auto& a = layout_.arrays[i];
    json mics = json::array();
    json mics_site = json::array();
    for (std::size_t m = 0; m < a.mic_count(); ++m) {
      mics.push_back(vec3(a.mics_m[m]));
      mics_site.push_back(vec3(a.mic_site_m(m)));
    }
    arrays.push_back(json{{"id", a.id},
                          {"index", i},
                          {"position_m", vec3(a.position_m)},
                          {"centre_m", vec3(a.mic_count() > 0 ? a.centre_site_m() : a.position_m)},
                          {"yaw_deg", a.yaw_deg},
                          {"mics_m", std::move(mics)},
                          {"mics_site_m", std::move(mics_site)}});
  }
  json zones = json::array();
  for (const auto& z : layout_.zones) {
    json polygon = json::array();
    for (const auto& p : z.polygon_m) polygon.push_back(json::array({p.x(), p.y()}));
    zones.push_back(json{{"name", z.name},
                         {"polygon_m", std::move(polygon)},
                         {"altitude_min_m", z.altitude_min_m},
                         {"altitude_max_m", z.altitude_max_m}});
  }
  return dump(json{{"arrays", std::move(arrays)},
                   {"zones", std::move(zones)},
                   {"speed_of_sound_mps", layout_.speed_of_sound_mps},
                   {"frame", "x east, y north, z up; metres"}});
}

std::string LiveState::tracks_json() const {
  double now = 0.0;
  double tracks_time = 0.0;
  std::vector<fusion::TrackReport> tracks;
  {
    std::lock_guard lock(mutex_);
    now = state_->now();
    tracks_time = state_->tracks_time_s;
    tracks = state_->tracks;
  }
  json list = json::array();
  for (const auto& track : tracks) list.push_back(track_json(track, layout_));
  return dump(json{{"t", now}, {"tracks_t", tracks_time}, {"tracks", std::move(list)}});
}

std::string LiveState::history_json(double since_s) const {
  double now = 0.0;
  std::vector<std::pair<int, std::vector<HistoryPoint>>> copy;
  {
    std::lock_guard lock(mutex_);
    now = state_->now();
    for (const auto& [id, points] : state_->history) {
      auto first = std::upper_bound(points.begin(), points.end(), since_s,
                                    [](double t, const HistoryPoint& p) { return t < p.time_s; });
      if (first == points.end()) continue;
      copy.emplace_back(id, std::vector<HistoryPoint>(first, points.end()));
    }
  }
  json tracks = json::array();
  for (const auto& [id, points] : copy) {
    json rows = json::array();
    for (const auto& p : points) {
      rows.push_back(json::array({p.time_s, p.position_m.x(), p.position_m.y(), p.position_m.z()}));
    }
    tracks.push_back(json{{"id", id}, {"points", std::move(rows)}});
  }
  return dump(json{{"t", now},
                   {"since", since_s},
                   {"columns", json::array({"t", "x_m", "y_m", "z_m"})},
                   {"tracks", std::move(tracks)}});
}

std::string LiveState::nodes_json() const {
  double now = 0.0;
  std::map<std::string, doa::NodeStatus> nodes;
  std::map<std::pair<std::string, int>, doa::DoaMeasurement> doas;
  std::map<std::string, std::pair<double, doa::PoseStamp>> poses;
  std::map<std::string, std::deque<State::PathPoint>> paths;
  {
    std::lock_guard lock(mutex_);
    now = state_->now();
    nodes = state_->nodes;
    doas = state_->doas;
    poses = state_->poses;
    paths = state_->paths;
  }
  // Every array of the layout, then any node the layout does not know (a misconfigured node
  // should be visible, not hidden).
  std::vector<std::string> ids;
  for (const auto& a : layout_.arrays) ids.push_back(a.id);
  for (const auto& [id, status] : nodes) {
    if (std::find(ids.begin(), ids.end(), id) == ids.end()) ids.push_back(id);
  }
  json list = json::array();
  for (const auto& id : ids) {
    json entry{{"array", id}};
    const auto it = nodes.find(id);
    std::string reason;
    if (it == nodes.end()) {
      reason = "no_status";
      entry["status"] = nullptr;
      entry["status_age_s"] = nullptr;
    } else {
      const double age = now - it->second.time_s;
      if (!it->second.alive) {
        reason = "not_alive";
      } else if (age > limits_.stale_after_s) {
        reason = "timeout";
      }
      entry["status"] = status_json(it->second);
      entry["status_age_s"] = age;
    }
    entry["stale"] = !reason.empty();
    entry["state"] = reason.empty() ? "alive" : "stale";
    entry["stale_reason"] = reason.empty() ? json(nullptr) : json(reason);
    json latest = json::array();
    for (auto d = doas.lower_bound({id, std::numeric_limits<int>::min()});
         d != doas.end() && d->first.first == id; ++d) {
      latest.push_back(doa_json(d->second));
    }
    entry["doa"] = std::move(latest);
    const auto pose = poses.find(id);
    entry["pose"] =
        pose == poses.end() ? json(nullptr) : pose_json(pose->second.first, pose->second.second);
    json path = json::array();
    if (const auto found = paths.find(id); found != paths.end()) {
      for (const auto& point : found->second) {
        path.push_back(json::array(
            {point.time_s, point.centre_m.x(), point.centre_m.y(), point.centre_m.z()}));
      }
    }
    entry["path"] = std::move(path);
    list.push_back(std::move(entry));
  }
  return dump(
      json{{"t", now}, {"stale_after_s", limits_.stale_after_s}, {"nodes", std::move(list)}});
}

std::string LiveState::alerts_json(double since_s) const {
  double now = 0.0;
  std::vector<fusion::ZoneEvent> alerts;
  {
    std::lock_guard lock(mutex_);
    now = state_->now();
    for (const auto& a : state_->alerts) {
      if (a.time_s > since_s) alerts.push_back(a);
    }
  }
  json list = json::array();
  for (const auto& a : alerts) list.push_back(alert_json(a));
  return dump(json{{"t", now}, {"alerts", std::move(list)}});
}

std::shared_ptr<EventQueue> LiveState::subscribe() {
  auto queue = std::make_shared<EventQueue>(limits_.stream_queue_events);
  // Prime with the current picture so a new client draws at once.
  queue->push(std::make_shared<const std::string>(sse_event("tracks", tracks_json())));
  queue->push(std::make_shared<const std::string>(sse_event("nodes", nodes_json())));
  std::lock_guard lock(subscribers_mutex_);
  subscribers_.push_back(queue);
  return queue;
}

void LiveState::unsubscribe(const std::shared_ptr<EventQueue>& queue) {
  queue->close();
  std::lock_guard lock(subscribers_mutex_);
  subscribers_.erase(std::remove(subscribers_.begin(), subscribers_.end(), queue),
                     subscribers_.end());
}

std::size_t LiveState::subscriber_count() const {
  std::lock_guard lock(subscribers_mutex_);
  return subscribers_.size();
}

std::int64_t LiveState::dropped_clients() const {
  std::lock_guard lock(subscribers_mutex_);
  return dropped_clients_;
}

void LiveState::broadcast(const std::string& event_name, std::string data) {
  const auto event = std::make_shared<const std::string>(sse_event(event_name, data));
  std::lock_guard lock(subscribers_mutex_);
  for (auto it = subscribers_.begin(); it != subscribers_.end();) {
    if ((*it)->push(event) && !(*it)->dropped()) {
      ++it;
    } else {
      // Full (a slow or stuck client) or closed: forget it; its server thread sees the drop and
      // ends the response.
      if ((*it)->dropped()) ++dropped_clients_;
      it = subscribers_.erase(it);
    }
  }
}

}  // namespace dronetrack::http_api
