#include "apps/jsonl_output.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "doa/array_geometry.hpp"

namespace dronetrack::apps {
namespace {
// A line that did not fit its buffer would be cut: refuse rather than write broken JSON.
void write_formatted(OutputFile& out, const char* buffer, std::size_t size, int length) {
  if (length < 0 || static_cast<std::size_t>(length) >= size)
    throw OutputError(out.name() + ": a line did not fit its " + std::to_string(size) +
                      "-byte buffer (an array id or zone name too long?)");
  out.write_line(buffer, static_cast<std::size_t>(length));
}
}  // namespace

int format_doa_line(const doa::DoaMeasurement& doa, char* buffer, std::size_t size) {
  const Eigen::Vector3d& u = doa.direction;
  const double azimuth_std_rad = std::sqrt(std::max(0.0, doa.azel_covariance_rad2(0, 0)));
  const double elevation_std_rad = std::sqrt(std::max(0.0, doa.azel_covariance_rad2(1, 1)));
  const double product = azimuth_std_rad * elevation_std_rad;
  const double correlation =
      product > 0.0 ? std::clamp(doa.azel_covariance_rad2(0, 1) / product, -1.0, 1.0) : 0.0;
  const int length = std::snprintf(
      buffer, size,
      R"({"t":%.6f,"array":"%s","direction":[%.9f,%.9f,%.9f],"azimuth_deg":%.5f,)"
      R"("elevation_deg":%.5f,"quality":%.4f,"snr_db":%.2f,"source":%d,"ambiguity":"%s",)"
      R"("azel_std_deg":[%.6f,%.6f],"azel_correlation":%.6f%s)",
      doa.time_s, doa.array_id.c_str(), u.x(), u.y(), u.z(), doa::azimuth_deg(u),
      doa::elevation_deg(u), doa.quality, doa.snr_db, doa.source_index,
      doa::to_string(doa.ambiguity), azimuth_std_rad * 180.0 / std::numbers::pi,
      elevation_std_rad * 180.0 / std::numbers::pi, correlation, doa.acoustic.valid ? "," : "}");
  if (length <= 0 || !doa.acoustic.valid || static_cast<std::size_t>(length) >= size) return length;
  const doa::AcousticFeatures& a = doa.acoustic;
  const int tail =
      std::snprintf(buffer + length, size - static_cast<std::size_t>(length),
                    R"("acoustic":{"fundamental_hz":%.2f,"comb_strength":%.4f,"harmonics":%d,)"
                    R"("broadband_share":%.4f,"comb_persistence":%.4f,"fundamental_spread":%.5f,)"
                    R"("level_modulation_db":%.3f,"history_s":%.2f}})",
                    a.fundamental_hz, a.comb_strength, a.harmonic_count, a.broadband_share,
                    a.comb_persistence, a.fundamental_spread, a.level_modulation_db, a.history_s);
  return tail < 0 ? tail : length + tail;
}

int format_track_line(double time_s, const fusion::TrackReport& track, char* buffer,
                      std::size_t size) {
  const Eigen::Vector3d& p = track.position_m;
  const Eigen::Vector3d& v = track.velocity_mps;
  const Eigen::Vector3d& a = track.acceleration_mps2;
  const Eigen::Vector3d s = track.position_std_m();
  return std::snprintf(
      buffer, size,
      R"({"t":%.3f,"id":%d,"position_m":[%.4f,%.4f,%.4f],"velocity_mps":[%.4f,%.4f,%.4f],)"
      R"("acceleration_mps2":[%.4f,%.4f,%.4f],"position_std_m":[%.4f,%.4f,%.4f],"status":"%s",)"
      R"("class":"%s","class_confidence":%.3f})",
      time_s, track.id, p.x(), p.y(), p.z(), v.x(), v.y(), v.z(), a.x(), a.y(), a.z(), s.x(), s.y(),
      s.z(), fusion::to_string(track.status), fusion::to_string(track.track_class),
      track.class_confidence);
}

int format_alert_line(const fusion::ZoneEvent& event, char* buffer, std::size_t size) {
  const Eigen::Vector3d& p = event.position_m;
  char previous[64] = "";
  if (event.kind == fusion::ZoneEventKind::class_changed)
    std::snprintf(previous, sizeof previous, R"("previous_class":"%s",)",
                  fusion::to_string(event.previous_class));
  return std::snprintf(buffer, size,
                       R"({"t":%.3f,"zone":"%s","track_id":%d,"event":"%s","class":"%s",%s)"
                       R"("position_m":[%.4f,%.4f,%.4f]})",
                       event.time_s, event.zone.c_str(), event.track_id,
                       fusion::to_string(fusion::kind_of(event)),
                       fusion::to_string(event.track_class), previous, p.x(), p.y(), p.z());
}

void AlertLinesWriter::on_zone_event(const fusion::ZoneEvent& event) {
  write_formatted(out_, buffer_, sizeof buffer_, format_alert_line(event, buffer_, sizeof buffer_));
}

void DoaLinesWriter::on_doa(const doa::DoaMeasurement& doa) {
  write_formatted(out_, buffer_, sizeof buffer_, format_doa_line(doa, buffer_, sizeof buffer_));
}

void TrackLinesWriter::on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) {
  for (const auto& track : tracks) {
    write_formatted(out_, buffer_, sizeof buffer_,
                    format_track_line(time_s, track, buffer_, sizeof buffer_));
  }
}

}  // namespace dronetrack::apps
