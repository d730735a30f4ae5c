#pragma once
// The site config (SPEC 3.1) as plain structs. Parsed and validated once, at start-up, in
// site_config.cpp; libraries take these structs, never file names.
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "doa/array_geometry.hpp"
#include "doa/doa_params.hpp"
#include "doa/pose_track.hpp"
#include "fusion/fusion_params.hpp"
#include "fusion/zone_monitor.hpp"

namespace dronetrack::config {

struct ArrayConfig {
  doa::ArrayGeometry geometry;
  std::filesystem::path recording;  // absolute (resolved against the config file); may be empty
  std::vector<int> channel_map;     // channel_map[mic] = channel of the recording/device
  std::optional<int> device;        // PortAudio device index for live capture
  // Site z of the ground under this array, where it differs from doa.ground_height_m (a site on
  // uneven ground): the ground-echo removal mirrors this array's mics in it.
  std::optional<double> ground_height_m;
  // A moving array (issue 15). pose_file: absolute (resolved against the config file), read and
  // checked at load into `pose`; replay stamps each DOA with the pose at its frame's time. The
  // geometry's position_m and attitude stay the array's nominal pose: the node's DSP (ground
  // echo, horizon, static null) works in that frame, and every DOA is turned to the pose at its
  // time when it is published. Empty: a fixed array.
  std::filesystem::path pose_file;
  doa::PoseTrack pose;
  double pose_max_gap_s = 1.0;  // larger gaps between pose lines (or live samples) are unknown
  // Live: the node takes this array's pose from the ArrayPose DDS topic (a GPS/INS adapter).
  bool pose_topic = false;
  bool moving() const { return !pose_file.empty() || pose_topic; }
};

struct DdsConfig {
  int domain_id = 0;
  // DDS Security on (docs/deployment.md, "DDS Security"): the directory scripts/site-pki.sh
  // made (ca.crt, governance.p7s, NAME.crt/.key, NAME-permissions.p7s); relative to the site
  // file. Empty: plain DDS.
  std::filesystem::path security_directory;
  bool secure() const { return !security_directory.empty(); }
};

struct HttpConfig {
  std::string bind = "127.0.0.1:8080";
  // Operator access beyond loopback (docs/http_api.md, "Access"): paths, relative to the site
  // file; the secrets stay in those files, never in the config.
  std::filesystem::path tls_certificate;  // PEM certificate chain
  std::filesystem::path tls_private_key;  // PEM private key
  std::filesystem::path users_file;       // `dronetrack passwd` lines
};

// Incident capture at each node (docs/deployment.md "Incident recordings"): a ring of the last
// ring_s seconds of raw audio per array on disk, and on every zone alert a clip from before_s
// before to after_s after it, with its time sidecar and the DOA and track lines of that window.
struct IncidentConfig {
  std::filesystem::path directory;  // absolute (resolved against the config file); empty: off
  double ring_s = 300.0;
  double before_s = 30.0;
  double after_s = 30.0;
  bool enabled() const { return !directory.empty(); }
};
// The fusion emits an alert some seconds after the audio that raised it (node latency, the
// reorder window): the ring keeps this much more than a clip so the clip's start is still held.
inline constexpr double kIncidentAlertDelay_s = 10.0;

struct SiteConfig {
  std::filesystem::path file;  // where it was read from (empty if built in memory)
  double speed_of_sound_mps = 343.0;
  std::vector<ArrayConfig> arrays;
  doa::DoaParams doa;
  fusion::FusionParams fusion;
  std::vector<fusion::Zone> zones;
  fusion::AlertPolicy alerts;  // "alerts": which tracks' zone entries alert
  DdsConfig dds;
  HttpConfig http;
  IncidentConfig incident;

  std::vector<doa::ArrayGeometry> geometries() const;
  // The DSP parameters of one array: `doa` with that array's own ground height, if it has one.
  doa::DoaParams doa_params(std::size_t array) const;
  // Index of the array with this id, or -1.
  int array_index(const std::string& id) const;
};

// All problems found, one line each: "arrays[1].mics_m[2]: expected 3 numbers, got 2".
class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(std::vector<std::string> problems);
  const std::vector<std::string>& problems() const { return problems_; }

 private:
  std::vector<std::string> problems_;
};

struct LoadOptions {
  // Check each recording exists and has one channel per mic (off when the recordings are about
  // to be written, e.g. by the simulator, or when capturing live).
  bool check_recordings = true;
  // The site feeds a fusion (replay, fusion): it needs at least 2 arrays.
  bool for_fusion = false;
  // Read and check each array's pose_file into ArrayConfig::pose (off when the pose files are
  // about to be written, e.g. by the simulator: pose_file is then only resolved).
  bool read_pose_files = true;
};

// Input bounds checked while parsing (docs/contract.md).
inline constexpr std::size_t kMaxArrays = 64;        // the fusion's 64-bit array mask
inline constexpr double kMinSampleRate_hz = 1000.0;  // as NodePipeline accepts
inline constexpr double kMaxSampleRate_hz = 1e6;
// Acoustic range is a few km: coordinates past 100 km are a unit or sign mistake, and past
// 1e15 m a double cannot hold a millimetre.
inline constexpr double kMaxSiteCoordinate_m = 1e5;

// Reads and validates a site config file. Throws ConfigError (message prefixed with the file
// name). Warnings (unknown keys) are appended to `warnings`.
SiteConfig load_site_config(const std::filesystem::path& file, std::vector<std::string>& warnings,
                            const LoadOptions& options = {});
// Same from text already read; `base_dir` resolves relative recording paths.
SiteConfig parse_site_config(const std::string& json_text, const std::filesystem::path& base_dir,
                             std::vector<std::string>& warnings, const LoadOptions& options = {});

}  // namespace dronetrack::config
