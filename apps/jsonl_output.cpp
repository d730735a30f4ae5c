#include "apps/jsonl_output.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>
#include <string_view>

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

// Builds a line in the caller's buffer with std::to_chars, which the standard defines to give
// printf's characters for "%.Nf" and "%d" (so the lines are the contract's formats, byte for
// byte) at a fraction of glibc's cost: snprintf was 4 % of a DOA-only replay's CPU.
class LineBuilder {
 public:
  LineBuilder(char* buffer, std::size_t size)
      : begin_(buffer), next_(buffer), end_(size > 0 ? buffer + size - 1 : buffer), size_(size) {}
  LineBuilder& text(std::string_view part) {
    if (static_cast<std::size_t>(end_ - next_) < part.size()) {
      overflow_ = true;
      return *this;
    }
    next_ = std::copy(part.begin(), part.end(), next_);
    return *this;
  }
  LineBuilder& fixed(double value, int precision) {
    return check(std::to_chars(next_, end_, value, std::chars_format::fixed, precision));
  }
  LineBuilder& integer(int value) { return check(std::to_chars(next_, end_, value)); }
  LineBuilder& vector3(const Eigen::Vector3d& value, int precision) {
    return text("[")
        .fixed(value.x(), precision)
        .text(",")
        .fixed(value.y(), precision)
        .text(",")
        .fixed(value.z(), precision)
        .text("]");
  }
  // The length written (NUL-terminated), or the buffer's size when the line did not fit.
  int finish() {
    if (size_ == 0) return 0;
    if (overflow_) return static_cast<int>(size_);
    *next_ = '\0';
    return static_cast<int>(next_ - begin_);
  }

 private:
  LineBuilder& check(std::to_chars_result result) {
    if (result.ec != std::errc()) {
      overflow_ = true;
    } else {
      next_ = result.ptr;
    }
    return *this;
  }

  char* begin_;
  char* next_;
  char* end_;  // one before the buffer's end: room for the NUL
  std::size_t size_;
  bool overflow_ = false;
};

// The issue-15 blocks (docs/contract.md): "pose" for a moving array, "cone" or "mirror_normal"
// for what a rank-deficient array measured.
void append_doa_geometry(const doa::DoaMeasurement& doa, LineBuilder& line) {
  constexpr double kDegPerRad = 180.0 / std::numbers::pi;
  if (doa.pose.moving) {
    const Eigen::Vector3d attitude = doa::attitude_deg_of(doa.pose.array_to_site);
    line.text(R"(,"pose":{"centre_m":)")
        .vector3(doa.pose.centre_m, 4)
        .text(R"(,"attitude_deg":)")
        .vector3(attitude, 4)
        .text("}");
  }
  if (doa.ambiguity == doa::DoaAmbiguity::cone) {
    line.text(R"(,"cone":{"axis":)")
        .vector3(doa.ambiguity_axis, 9)
        .text(R"(,"angle_deg":)")
        .fixed(doa.cone_angle_rad * kDegPerRad, 5)
        .text(R"(,"angle_std_deg":)")
        .fixed(std::sqrt(std::max(0.0, doa.cone_angle_variance_rad2)) * kDegPerRad, 6);
    const int peaks = std::clamp(doa.cone_peak_count, 0, doa::kMaxConePeaks);
    if (peaks > 0) {
      for (int pass = 0; pass < 2; ++pass) {
        line.text(pass == 0 ? R"(,"peaks_deg":[)" : R"(,"peak_weights":[)");
        for (int k = 0; k < peaks; ++k) {
          const auto index = static_cast<std::size_t>(k);
          const double value =
              pass == 0 ? doa.cone_peak_angle_rad[index] * kDegPerRad : doa.cone_peak_weight[index];
          line.text(k == 0 ? "" : ",").fixed(value, 5);
        }
        line.text("]");
      }
    }
    line.text("}");
  } else if (doa.ambiguity == doa::DoaAmbiguity::mirror_up_down) {
    line.text(R"(,"mirror_normal":)").vector3(doa.ambiguity_axis, 9);
  }
}
}  // namespace

int format_doa_line(const doa::DoaMeasurement& doa, char* buffer, std::size_t size) {
  const Eigen::Vector3d& u = doa.direction;
  const double azimuth_std_rad = std::sqrt(std::max(0.0, doa.azel_covariance_rad2(0, 0)));
  const double elevation_std_rad = std::sqrt(std::max(0.0, doa.azel_covariance_rad2(1, 1)));
  const double product = azimuth_std_rad * elevation_std_rad;
  const double correlation =
      product > 0.0 ? std::clamp(doa.azel_covariance_rad2(0, 1) / product, -1.0, 1.0) : 0.0;
  LineBuilder line(buffer, size);
  line.text(R"({"t":)")
      .fixed(doa.time_s, 6)
      .text(R"(,"array":")")
      .text(doa.array_id)
      .text(R"(","direction":)")
      .vector3(u, 9)
      .text(R"(,"azimuth_deg":)")
      .fixed(doa::azimuth_deg(u), 5)
      .text(R"(,"elevation_deg":)")
      .fixed(doa::elevation_deg(u), 5)
      .text(R"(,"quality":)")
      .fixed(doa.quality, 4)
      .text(R"(,"snr_db":)")
      .fixed(doa.snr_db, 2)
      .text(R"(,"source":)")
      .integer(doa.source_index)
      .text(R"(,"ambiguity":")")
      .text(doa::to_string(doa.ambiguity))
      .text(R"(","azel_std_deg":[)")
      .fixed(azimuth_std_rad * 180.0 / std::numbers::pi, 6)
      .text(",")
      .fixed(elevation_std_rad * 180.0 / std::numbers::pi, 6)
      .text(R"(],"azel_correlation":)")
      .fixed(correlation, 6);
  append_doa_geometry(doa, line);
  if (doa.acoustic.valid) {
    const doa::AcousticFeatures& a = doa.acoustic;
    line.text(R"(,"acoustic":{"fundamental_hz":)")
        .fixed(a.fundamental_hz, 2)
        .text(R"(,"comb_strength":)")
        .fixed(a.comb_strength, 4)
        .text(R"(,"harmonics":)")
        .integer(a.harmonic_count)
        .text(R"(,"broadband_share":)")
        .fixed(a.broadband_share, 4)
        .text(R"(,"comb_persistence":)")
        .fixed(a.comb_persistence, 4)
        .text(R"(,"fundamental_spread":)")
        .fixed(a.fundamental_spread, 5)
        .text(R"(,"level_modulation_db":)")
        .fixed(a.level_modulation_db, 3)
        .text(R"(,"history_s":)")
        .fixed(a.history_s, 2)
        .text("}");
  }
  return line.text("}").finish();
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
