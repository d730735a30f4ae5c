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

namespace {
// Appends with snprintf at `length`; a negative or overflowing result is passed on for the
// caller's check.
template <class... Args>
int append_formatted(char* buffer, std::size_t size, int length, const char* format, Args... args) {
  if (length < 0 || static_cast<std::size_t>(length) >= size) return length;
  const int tail =
      std::snprintf(buffer + length, size - static_cast<std::size_t>(length), format, args...);
  return tail < 0 ? tail : length + tail;
}

// The issue-15 blocks (docs/contract.md): "pose" for a moving array, "cone" or "mirror_normal"
// for what a rank-deficient array measured. Each with a leading comma.
int append_doa_geometry(const doa::DoaMeasurement& doa, char* buffer, std::size_t size,
                        int length) {
  constexpr double kDegPerRad = 180.0 / std::numbers::pi;
  if (doa.pose.moving) {
    const Eigen::Vector3d& c = doa.pose.centre_m;
    const Eigen::Vector3d attitude = doa::attitude_deg_of(doa.pose.array_to_site);
    length =
        append_formatted(buffer, size, length,
                         R"(,"pose":{"centre_m":[%.4f,%.4f,%.4f],"attitude_deg":[%.4f,%.4f,%.4f]})",
                         c.x(), c.y(), c.z(), attitude(0), attitude(1), attitude(2));
  }
  const Eigen::Vector3d& axis = doa.ambiguity_axis;
  if (doa.ambiguity == doa::DoaAmbiguity::cone) {
    length = append_formatted(
        buffer, size, length,
        R"(,"cone":{"axis":[%.9f,%.9f,%.9f],"angle_deg":%.5f,"angle_std_deg":%.6f)", axis.x(),
        axis.y(), axis.z(), doa.cone_angle_rad * kDegPerRad,
        std::sqrt(std::max(0.0, doa.cone_angle_variance_rad2)) * kDegPerRad);
    const int peaks = std::clamp(doa.cone_peak_count, 0, doa::kMaxConePeaks);
    if (peaks > 0) {
      for (int pass = 0; pass < 2; ++pass) {
        length = append_formatted(buffer, size, length, "%s",
                                  pass == 0 ? R"(,"peaks_deg":[)" : R"(,"peak_weights":[)");
        for (int k = 0; k < peaks; ++k) {
          const auto index = static_cast<std::size_t>(k);
          const double value =
              pass == 0 ? doa.cone_peak_angle_rad[index] * kDegPerRad : doa.cone_peak_weight[index];
          length = append_formatted(buffer, size, length, k == 0 ? "%.5f" : ",%.5f", value);
        }
        length = append_formatted(buffer, size, length, "%s", "]");
      }
    }
    length = append_formatted(buffer, size, length, "%s", "}");
  } else if (doa.ambiguity == doa::DoaAmbiguity::mirror_up_down) {
    length = append_formatted(buffer, size, length, R"(,"mirror_normal":[%.9f,%.9f,%.9f])",
                              axis.x(), axis.y(), axis.z());
  }
  return length;
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
      R"("azel_std_deg":[%.6f,%.6f],"azel_correlation":%.6f)",
      doa.time_s, doa.array_id.c_str(), u.x(), u.y(), u.z(), doa::azimuth_deg(u),
      doa::elevation_deg(u), doa.quality, doa.snr_db, doa.source_index,
      doa::to_string(doa.ambiguity), azimuth_std_rad * 180.0 / std::numbers::pi,
      elevation_std_rad * 180.0 / std::numbers::pi, correlation);
  int total = append_doa_geometry(doa, buffer, size, length);
  if (doa.acoustic.valid) {
    const doa::AcousticFeatures& a = doa.acoustic;
    total = append_formatted(
        buffer, size, total,
        R"(,"acoustic":{"fundamental_hz":%.2f,"comb_strength":%.4f,"harmonics":%d,)"
        R"("broadband_share":%.4f,"comb_persistence":%.4f,"fundamental_spread":%.5f,)"
        R"("level_modulation_db":%.3f,"history_s":%.2f})",
        a.fundamental_hz, a.comb_strength, a.harmonic_count, a.broadband_share, a.comb_persistence,
        a.fundamental_spread, a.level_modulation_db, a.history_s);
  }
  return append_formatted(buffer, size, total, "%s", "}");
}

int format_track_line(double time_s, const fusion::TrackReport& track, char* buffer,
                      std::size_t size) {
  const Eigen::Vector3d& p = track.position_m;
  const Eigen::Vector3d& v = track.velocity_mps;
  const Eigen::Vector3d& a = track.acceleration_mps2;
  const Eigen::Vector3d s = track.position_std_m();
  const int length = std::snprintf(
      buffer, size,
      R"({"t":%.3f,"id":%d,"position_m":[%.4f,%.4f,%.4f],"velocity_mps":[%.4f,%.4f,%.4f],)"
      R"("acceleration_mps2":[%.4f,%.4f,%.4f],"position_std_m":[%.4f,%.4f,%.4f],"status":"%s",)"
      R"("class":"%s","class_confidence":%.3f%s)",
      time_s, track.id, p.x(), p.y(), p.z(), v.x(), v.y(), v.z(), a.x(), a.y(), a.z(), s.x(), s.y(),
      s.z(), fusion::to_string(track.status), fusion::to_string(track.track_class),
      track.class_confidence, track.one_array ? "," : "}");
  if (length <= 0 || !track.one_array) return length;
  return append_formatted(buffer, size, length, R"("one_array":true,"hypotheses":%d})",
                          track.hypotheses);
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

std::string format_tdoa_line(const doa::DoaMeasurement& doa) {
  char buffer[160];
  std::string text;
  std::snprintf(buffer, sizeof buffer, R"({"t":%.6f,"array":")", doa.time_s);
  text += buffer;
  text += doa.array_id;
  std::snprintf(buffer, sizeof buffer, R"(","source":%d,"direction":[%.9f,%.9f,%.9f],"tdoa_s":[)",
                doa.source_index, doa.direction.x(), doa.direction.y(), doa.direction.z());
  text += buffer;
  for (int p = 0; p < doa.pair_count; ++p) {
    std::snprintf(buffer, sizeof buffer, p == 0 ? "%.9e" : ",%.9e",
                  doa.tdoa_s[static_cast<std::size_t>(p)]);
    text += buffer;
  }
  return text + "]}";
}

void TdoaLinesWriter::on_doa(const doa::DoaMeasurement& doa) {
  // A cone or a mirror's pair delays hold no direction to check them against.
  if (doa.ambiguity == doa::DoaAmbiguity::none) {
    const std::string line = format_tdoa_line(doa);
    out_.write_line(line.data(), line.size());
  }
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
