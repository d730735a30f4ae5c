#pragma once
// A small populated site for the HTTP API tests, and a reader for Server-Sent Events.
#include <string>
#include <vector>

#include "http_api/live_state.hpp"

namespace dronetrack::http_api::test {

// Two arrays (A1 at the origin, A2 at (40, 0, 1.5) rotated 90 degrees) and one square zone.
inline SiteLayout two_array_layout() {
  SiteLayout layout;
  for (int i = 0; i < 2; ++i) {
    doa::ArrayGeometry a;
    a.id = i == 0 ? "A1" : "A2";
    a.position_m = i == 0 ? Eigen::Vector3d(0, 0, 1.5) : Eigen::Vector3d(40, 0, 1.5);
    a.yaw_deg = i == 0 ? 0.0 : 90.0;
    a.mics_m = {{0.1, 0, 0}, {-0.1, 0, 0}, {0, 0.1, 0}, {0, -0.1, 0.1}};
    layout.arrays.push_back(a);
  }
  fusion::Zone pad;
  pad.name = "pad";
  pad.polygon_m = {{10, 10}, {30, 10}, {30, 30}, {10, 30}};
  pad.altitude_min_m = 0.0;
  pad.altitude_max_m = 120.0;
  layout.zones.push_back(pad);
  return layout;
}

inline fusion::TrackReport make_track(int id, double time_s, Eigen::Vector3d position_m,
                                      Eigen::Vector3d velocity_mps) {
  fusion::TrackReport t;
  t.id = id;
  t.time_s = time_s;
  t.position_m = position_m;
  t.velocity_mps = velocity_mps;
  t.covariance = Eigen::Matrix<double, 9, 9>::Identity();
  t.covariance(0, 0) = 4.0;
  t.covariance(1, 1) = 9.0;
  t.covariance(2, 2) = 16.0;
  t.covariance(0, 1) = t.covariance(1, 0) = 1.5;
  t.status = fusion::TrackStatus::confirmed;
  t.contributing_arrays = 0b11;
  t.last_update_s = time_s;
  return t;
}

struct SseEvent {
  std::string name;
  std::string data;
};

// Accumulates a byte stream and splits complete events ("event: X\ndata: Y\n\n"); comments
// and partial events stay in the buffer.
class SseParser {
 public:
  void feed(const char* data, std::size_t size, std::vector<SseEvent>& out) {
    buffer_.append(data, size);
    for (auto end = buffer_.find("\n\n"); end != std::string::npos; end = buffer_.find("\n\n")) {
      const std::string block = buffer_.substr(0, end);
      buffer_.erase(0, end + 2);
      SseEvent event;
      std::size_t begin = 0;
      while (begin < block.size()) {
        const std::size_t line_end = std::min(block.find('\n', begin), block.size());
        const std::string line = block.substr(begin, line_end - begin);
        if (line.rfind("event: ", 0) == 0) event.name = line.substr(7);
        if (line.rfind("data: ", 0) == 0) event.data += line.substr(6);
        begin = line_end + 1;
      }
      if (!event.name.empty()) out.push_back(std::move(event));
    }
  }

 private:
  std::string buffer_;
};

}  // namespace dronetrack::http_api::test
