#include "capture/recording_time.hpp"

#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "common/output_file.hpp"

namespace dronetrack::capture {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;
constexpr std::int64_t kNsPerDay = 86'400 * kNsPerS;
// A sidecar is a few hundred bytes: anything past this is not one.
constexpr std::uintmax_t kMaxSidecarBytes = 64 * 1024;

// Floor division: times before 1970 round towards the earlier second.
std::int64_t floor_div(std::int64_t value, std::int64_t divisor) {
  const std::int64_t quotient = value / divisor;
  return (value % divisor != 0 && value < 0) ? quotient - 1 : quotient;
}

}  // namespace

std::filesystem::path time_sidecar_path(const std::filesystem::path& recording) {
  std::filesystem::path sidecar = recording;
  sidecar += ".json";
  return sidecar;
}

std::string format_utc(std::int64_t unix_ns) {
  const std::int64_t seconds = floor_div(unix_ns, kNsPerS);
  const std::int64_t micros = (unix_ns - seconds * kNsPerS) / 1000;
  const auto time = static_cast<std::time_t>(seconds);
  std::tm parts{};
  gmtime_r(&time, &parts);
  char text[64];
  std::snprintf(text, sizeof text, "%04d-%02d-%02dT%02d:%02d:%02d.%06lldZ", parts.tm_year + 1900,
                parts.tm_mon + 1, parts.tm_mday, parts.tm_hour, parts.tm_min, parts.tm_sec,
                static_cast<long long>(micros));
  return text;
}

std::optional<std::int64_t> parse_utc(const std::string& text) {
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0, consumed = 0;
  if (std::sscanf(text.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d%n", &year, &month, &day, &hour, &minute,
                  &second, &consumed) != 6 ||
      consumed != 19)
    return std::nullopt;
  if (month < 1 || month > 12 || day < 1 || day > 31 || hour > 23 || minute > 59 || second > 60)
    return std::nullopt;
  std::size_t at = 19;
  std::int64_t fraction_ns = 0;
  if (at < text.size() && text[at] == '.') {
    std::int64_t scale = kNsPerS / 10;
    for (++at; at < text.size() && text[at] >= '0' && text[at] <= '9'; ++at) {
      if (scale == 0) return std::nullopt;  // more than nanoseconds
      fraction_ns += (text[at] - '0') * scale;
      scale /= 10;
    }
  }
  if (at + 1 != text.size() || text[at] != 'Z') return std::nullopt;
  std::tm parts{};
  parts.tm_year = year - 1900;
  parts.tm_mon = month - 1;
  parts.tm_mday = day;
  parts.tm_hour = hour;
  parts.tm_min = minute;
  parts.tm_sec = second;
  const std::time_t seconds = timegm(&parts);
  return static_cast<std::int64_t>(seconds) * kNsPerS + fraction_ns;
}

std::uint64_t samples_since_midnight(std::int64_t unix_ns, double sample_rate_hz) {
  const std::int64_t into_day_ns = unix_ns - floor_div(unix_ns, kNsPerDay) * kNsPerDay;
  return static_cast<std::uint64_t>(
      std::llround(static_cast<double>(into_day_ns) * 1e-9 * sample_rate_hz));
}

std::optional<RecordingTime> read_recording_time(const std::filesystem::path& recording) {
  const std::filesystem::path sidecar = time_sidecar_path(recording);
  std::error_code error;
  if (!std::filesystem::exists(sidecar, error)) return std::nullopt;
  const std::string name = sidecar.string();
  const auto fail = [&](const std::string& what) -> std::runtime_error {
    return std::runtime_error(name + ": " + what);
  };
  const std::uintmax_t bytes = std::filesystem::file_size(sidecar, error);
  if (error) throw fail("cannot read (" + error.message() + ")");
  if (bytes > kMaxSidecarBytes)
    throw fail("not a time sidecar (" + std::to_string(bytes) + " bytes, at most " +
               std::to_string(kMaxSidecarBytes) + ")");
  std::ifstream in(sidecar);
  std::stringstream text;
  text << in.rdbuf();
  if (!in) throw fail("cannot read");
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::exception& parse_error) {
    throw fail(std::string("not JSON (") + parse_error.what() + ")");
  }
  if (!document.is_object()) throw fail("expected a JSON object");
  const auto key = [&](const char* field) -> const nlohmann::json& {
    if (!document.contains(field)) throw fail(std::string(field) + ": missing");
    return document[field];
  };
  RecordingTime time;
  const nlohmann::json& array = key("array");
  if (!array.is_string() || array.get<std::string>().empty())
    throw fail("array: expected the array id (a non-empty string)");
  time.array_id = array.get<std::string>();
  const nlohmann::json& unix_ns = key("utc_start_unix_ns");
  if (!unix_ns.is_number_integer()) throw fail("utc_start_unix_ns: expected an integer");
  time.utc_start_unix_ns = unix_ns.get<std::int64_t>();
  const nlohmann::json& iso = key("utc_start");
  const std::optional<std::int64_t> iso_ns =
      iso.is_string() ? parse_utc(iso.get<std::string>()) : std::nullopt;
  if (!iso_ns) throw fail("utc_start: expected UTC as 2026-11-26T04:53:27.123456Z");
  // The two spellings of one instant: a hand edit of one but not the other is refused.
  if (std::llabs(*iso_ns - time.utc_start_unix_ns) >= 1000)
    throw fail("utc_start " + iso.get<std::string>() + " and utc_start_unix_ns " +
               std::to_string(time.utc_start_unix_ns) + " (" + format_utc(time.utc_start_unix_ns) +
               ") disagree");
  const nlohmann::json& rate = key("sample_rate_hz");
  if (!rate.is_number() || !(rate.get<double>() > 0.0) || !std::isfinite(rate.get<double>()))
    throw fail("sample_rate_hz: expected a positive number");
  time.sample_rate_hz = rate.get<double>();
  const nlohmann::json& first = key("first_sample");
  if (!first.is_number_integer() || first.get<std::int64_t>() < 0)
    throw fail("first_sample: expected an integer >= 0");
  time.first_sample = first.get<std::int64_t>();
  const nlohmann::json& channels = key("channels");
  if (!channels.is_number_integer() || channels.get<std::int64_t>() < 1 ||
      channels.get<std::int64_t>() > 1024)
    throw fail("channels: expected an integer from 1 to 1024");
  time.channels = channels.get<int>();
  if (document.contains("channel_order")) {
    const nlohmann::json& order = document["channel_order"];
    if (!order.is_string() || (order != "input" && order != "mic"))
      throw fail("channel_order: expected \"input\" or \"mic\"");
    time.channel_order = order.get<std::string>();
  }
  if (document.contains("clock") && document["clock"].is_string())
    time.clock = document["clock"].get<std::string>();
  if (document.contains("software_version") && document["software_version"].is_string())
    time.software_version = document["software_version"].get<std::string>();
  return time;
}

void write_recording_time(const std::filesystem::path& recording, const RecordingTime& time) {
  nlohmann::ordered_json document;
  document["array"] = time.array_id;
  document["utc_start"] = format_utc(time.utc_start_unix_ns);
  document["utc_start_unix_ns"] = time.utc_start_unix_ns;
  // 48000, not 48000.0: the usual whole rates read as integers everywhere.
  if (time.sample_rate_hz == std::floor(time.sample_rate_hz) && time.sample_rate_hz < 1e9)
    document["sample_rate_hz"] = static_cast<std::int64_t>(time.sample_rate_hz);
  else
    document["sample_rate_hz"] = time.sample_rate_hz;
  document["first_sample"] = time.first_sample;
  document["channels"] = time.channels;
  document["channel_order"] = time.channel_order;
  document["clock"] = time.clock;
  document["software_version"] = time.software_version;
  OutputFile out(time_sidecar_path(recording));
  out.write(document.dump(2));
  out.commit();
}

}  // namespace dronetrack::capture
