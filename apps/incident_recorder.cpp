#include "apps/incident_recorder.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "apps/jsonl_output.hpp"
#include "capture/audio_file_writer.hpp"
#include "common/log.hpp"
#include "common/output_file.hpp"

namespace dronetrack::apps {
namespace {

// More alerts than this waiting for their window (a swarm entering every zone at once) are
// logged and dropped rather than held without bound.
constexpr std::size_t kMaxPendingClips = 16;

// A zone name as part of a directory name: letters, digits, '-' and '_' kept, the rest '_'.
std::string file_safe(const std::string& text) {
  std::string safe;
  for (const char c : text)
    safe += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_') ? c : '_';
  return safe.empty() ? std::string("request") : safe;
}

// "2026-11-26T04:53:27.123456Z" -> "20261126T045327.123456Z".
std::string compact_utc(std::int64_t unix_ns) {
  std::string text = capture::format_utc(unix_ns);
  text.erase(std::remove_if(text.begin(), text.end(), [](char c) { return c == '-' || c == ':'; }),
             text.end());
  return text;
}

// A relative path key of the site document made absolute against the site's folder, so the
// clip's site.json still finds it.
void make_absolute(nlohmann::ordered_json& object, const char* key,
                   const std::filesystem::path& base) {
  if (!object.is_object() || !object.contains(key) || !object[key].is_string()) return;
  const std::filesystem::path path(object[key].get<std::string>());
  if (!path.empty() && path.is_relative()) object[key] = (base / path).lexically_normal().string();
}

}  // namespace

struct IncidentRecorder::Lane {
  IncidentArray array;
  std::string id;
  capture::DiskAudioRing ring;
  std::int64_t ring_errors_logged = 0;
};

IncidentRecorder::IncidentRecorder(const config::SiteConfig& site,
                                   std::vector<IncidentArray> arrays, IncidentClock clock)
    : site_(site),
      settings_(site.incident),
      clock_(std::move(clock)),
      // Room for the window's lines: 100 DOAs/s per array (4 sources at 20 frames/s is 80) of
      // 500 bytes (~350 plain, ~650 with the acoustic block), 100 track lines/s; a busier site
      // loses the oldest lines of a clip's window (3.5 MB per array for the default 70 s).
      doa_lines_(static_cast<std::size_t>(history_s() * 100.0 * 500.0) * arrays.size(),
                 static_cast<std::size_t>(history_s() * 100.0) * arrays.size()),
      track_lines_(static_cast<std::size_t>(history_s() * 100.0 * 400.0),
                   static_cast<std::size_t>(history_s() * 100.0)) {
  const std::filesystem::path ring_folder = settings_.directory / "ring";
  std::error_code error;
  std::filesystem::create_directories(ring_folder, error);
  if (error)
    throw std::runtime_error(ring_folder.string() + ": cannot create the incident directory (" +
                             error.message() + ")");
  std::size_t widest = 0;
  for (const IncidentArray& array : arrays) {
    const std::string& id = site.arrays.at(static_cast<std::size_t>(array.site_index)).geometry.id;
    const auto capacity =
        static_cast<std::int64_t>(std::ceil(settings_.ring_s * array.sample_rate_hz));
    lanes_.push_back(std::unique_ptr<Lane>(new Lane{
        array, id, capture::DiskAudioRing(ring_folder / (id + ".f32"), array.channels, capacity)}));
    widest = std::max(widest, static_cast<std::size_t>(std::ceil(array.sample_rate_hz)) *
                                  static_cast<std::size_t>(array.channels));
  }
  chunk_.resize(widest);
  log::info("incident: recording the last ", settings_.ring_s, " s of ", lanes_.size(),
            " array(s) in ", ring_folder.string(), "; clips ", settings_.before_s, " s before to ",
            settings_.after_s, " s after each alert into ", settings_.directory.string());
}

IncidentRecorder::~IncidentRecorder() = default;

IncidentRecorder::Lane* IncidentRecorder::lane_of(int site_index) const {
  for (const auto& lane : lanes_)
    if (lane->array.site_index == site_index) return lane.get();
  return nullptr;
}

void IncidentRecorder::on_audio(int array_index, const doa::AudioBlockView& block) {
  if (Lane* lane = lane_of(array_index)) lane->ring.append(block);
}

double IncidentRecorder::history_s() const {
  return site_.incident.before_s + site_.incident.after_s + config::kIncidentAlertDelay_s;
}

void IncidentRecorder::on_doa(const doa::DoaMeasurement& doa) {
  const int length = format_doa_line(doa, line_, sizeof line_);
  if (length <= 0 || static_cast<std::size_t>(length) >= sizeof line_) return;
  doa_lines_.add(doa.time_s, line_, static_cast<std::size_t>(length));
  doa_lines_.drop_before(doa.time_s - history_s());
}

void IncidentRecorder::on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) {
  for (const fusion::TrackReport& track : tracks) {
    const int length = format_track_line(time_s, track, line_, sizeof line_);
    if (length <= 0 || static_cast<std::size_t>(length) >= sizeof line_) continue;
    track_lines_.add(time_s, line_, static_cast<std::size_t>(length));
  }
  track_lines_.drop_before(time_s - history_s());
}

void IncidentRecorder::on_zone_event(const fusion::ZoneEvent& event) {
  if (fusion::kind_of(event) != fusion::ZoneEventKind::entered) return;
  char buffer[512];
  const int length = format_alert_line(event, buffer, sizeof buffer);
  const std::string line =
      length > 0 && static_cast<std::size_t>(length) < sizeof buffer ? buffer : "";
  request(event.time_s, file_safe(event.zone) + "-track" + std::to_string(event.track_id), line);
}

void IncidentRecorder::request(double time_s, const std::string& label,
                               const std::string& event_line) {
  if (pending_.size() >= kMaxPendingClips) {
    ++requests_dropped_;
    log::error("incident: ", pending_.size(), " clips already waiting; the one at t ", time_s,
               " s (", label, ") is not saved (", requests_dropped_, " dropped so far)");
    return;
  }
  const auto alert_ns = clock_.utc_start_unix_ns + std::llround(time_s * 1e9);
  std::string name = compact_utc(alert_ns) + "-" + label;
  // A node's clip (one array of several) names its array: nodes may share a directory.
  if (lanes_.size() == 1 && site_.arrays.size() > 1) name.append("-").append(lanes_[0]->id);
  pending_.push_back({time_s, std::move(name), event_line});
}

bool IncidentRecorder::ready(const Pending& incident) const {
  const double end_s = incident.time_s + settings_.after_s;
  if (clock_.with_fusion && fusion_time_s_ < end_s) return false;
  return std::all_of(lanes_.begin(), lanes_.end(), [&](const auto& lane) {
    return static_cast<double>(lane->ring.end_sample()) >= end_s * lane->array.sample_rate_hz;
  });
}

void IncidentRecorder::service(bool at_end) {
  for (auto& lane : lanes_) {
    if (lane->ring.write_errors() == lane->ring_errors_logged) continue;
    log::error("incident: ", lane->ring.file().string(), ": ",
               lane->ring.write_errors() - lane->ring_errors_logged, " block write(s) failed (",
               std::strerror(lane->ring.last_errno()),
               "); the node goes on, clips lack that audio");
    lane->ring_errors_logged = lane->ring.write_errors();
  }
  auto next = pending_.begin();
  while (next != pending_.end()) {
    if (!at_end && !ready(*next)) {
      ++next;
      continue;
    }
    save(*next);
    next = pending_.erase(next);
  }
}

void IncidentRecorder::save(const Pending& incident) {
  const std::filesystem::path folder = settings_.directory / incident.name;
  std::filesystem::path partial = folder;
  partial += ".partial";
  try {
    std::filesystem::create_directories(partial);
    // Whole seconds of stream time: the clip's frames and ticks fall where the run's did.
    double from_s = std::floor(std::max(0.0, incident.time_s - settings_.before_s));
    double to_s = incident.time_s + settings_.after_s;
    for (const auto& lane : lanes_) {
      const double rate_hz = lane->array.sample_rate_hz;
      from_s =
          std::max(from_s, std::ceil(static_cast<double>(lane->ring.oldest_sample()) / rate_hz));
      to_s = std::min(to_s, static_cast<double>(lane->ring.end_sample()) / rate_hz);
    }
    if (!(to_s > from_s))
      throw std::runtime_error("no audio held for t " + std::to_string(from_s) + " to " +
                               std::to_string(to_s) + " s");
    for (const auto& lane : lanes_) {
      const double rate_hz = lane->array.sample_rate_hz;
      write_clip(*lane, partial, std::llround(from_s * rate_hz),
                 std::min<std::int64_t>(lane->ring.end_sample(),
                                        std::llround(std::floor(to_s * rate_hz))));
    }
    write_lines(partial / "doa.jsonl", doa_lines_, from_s, to_s);
    write_lines(partial / "tracks.jsonl", track_lines_, from_s, to_s);
    if (!incident.event_line.empty()) {
      OutputFile alert(partial / "alert.json");
      alert.write(incident.event_line);
      alert.commit();
    }
    if (lanes_.size() == site_.arrays.size() && !site_.file.empty())
      write_site(partial / "site.json");
    std::filesystem::rename(partial, folder);
    ++clips_saved_;
    log::info("incident: saved ", folder.string(), " (t ", from_s, " to ", to_s, " s)");
  } catch (const std::exception& failure) {
    ++clip_errors_;
    log::error("incident: ", folder.string(), ": ", failure.what(),
               "; not saved, the node goes on");
    std::error_code ignored;
    std::filesystem::remove_all(partial, ignored);
  }
}

void IncidentRecorder::write_clip(Lane& lane, const std::filesystem::path& folder,
                                  std::int64_t first_sample, std::int64_t end_sample) {
  capture::RecordingTime time;
  time.array_id = lane.id;
  time.sample_rate_hz = lane.array.sample_rate_hz;
  time.utc_start_unix_ns =
      clock_.utc_start_unix_ns +
      std::llround(static_cast<double>(first_sample) / time.sample_rate_hz * 1e9);
  time.first_sample = first_sample;
  time.channels = lane.array.channels;
  time.channel_order = "mic";
  time.clock = clock_.clock;
  time.software_version = DRONETRACK_VERSION;
  capture::AudioFileWriter writer(folder / (lane.id + ".wav"), time);
  const auto chunk_frames = static_cast<std::int64_t>(chunk_.size()) / lane.array.channels;
  for (std::int64_t at = first_sample; at < end_sample; at += chunk_frames) {
    const auto frames = static_cast<std::size_t>(std::min(chunk_frames, end_sample - at));
    if (!lane.ring.read(at, frames, chunk_.data()))
      throw std::runtime_error(lane.ring.file().string() + ": samples " + std::to_string(at) +
                               " to " + std::to_string(at + static_cast<std::int64_t>(frames)) +
                               " are not held (lost to a write or read error)");
    writer.write(chunk_.data(), frames);
  }
  writer.commit();
}

void IncidentRecorder::write_lines(const std::filesystem::path& file, const LineHistory& lines,
                                   double from_s, double to_s) {
  OutputFile out(file);
  lines.for_each(from_s, to_s,
                 [&](const char* text, std::size_t length) { out.write_line(text, length); });
  out.commit();
}

void IncidentRecorder::write_site(const std::filesystem::path& file) const {
  std::ifstream in(site_.file);
  nlohmann::ordered_json document = nlohmann::ordered_json::parse(in);
  const std::filesystem::path base = std::filesystem::absolute(site_.file).parent_path();
  document.erase("incident");  // a replayed clip raises the same alert: no clip of the clip
  for (auto& array : document["arrays"]) {
    array["recording"] = array["id"].get<std::string>() + ".wav";
    array.erase("channel_map");  // clips are in mic order
    make_absolute(array, "pose_file", base);
  }
  if (document.contains("dds") && document["dds"].contains("security"))
    make_absolute(document["dds"]["security"], "directory", base);
  if (document.contains("http"))
    for (const char* key : {"tls_certificate", "tls_private_key", "users_file"})
      make_absolute(document["http"], key, base);
  OutputFile out(file);
  out.write(document.dump(2));
  out.commit();
}

std::int64_t IncidentRecorder::write_errors(int site_index) const {
  const Lane* lane = lane_of(site_index);
  return clip_errors_ + (lane ? lane->ring.write_errors() : 0);
}

void IncidentRecorder::fill_status(doa::NodeStatus& status) const {
  status.incident_clips = clips_saved_;
  status.incident_write_errors = write_errors(site_.array_index(status.array_id));
}

}  // namespace dronetrack::apps
