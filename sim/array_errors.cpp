#include "sim/array_errors.hpp"

#include <algorithm>
#include <cmath>

#include "sim/random.hpp"

namespace dronetrack::sim {
namespace {
constexpr std::uint64_t kArrayErrors = 0xCA1B;
}  // namespace

double ArrayErrors::recording_delay_s(std::size_t mic) const {
  return clock_offset_s + (mic < channel_delay_s.size() ? channel_delay_s[mic] : 0.0);
}

double ArrayErrors::gain(std::size_t mic) const {
  return mic < channel_gain_db.size() ? std::pow(10.0, channel_gain_db[mic] / 20.0) : 1.0;
}

bool ArrayErrors::dead(std::size_t mic) const {
  return std::find(dead_mics.begin(), dead_mics.end(), static_cast<int>(mic)) != dead_mics.end();
}

bool ArrayErrors::flipped(std::size_t mic) const {
  return std::find(flipped_mics.begin(), flipped_mics.end(), static_cast<int>(mic)) !=
         flipped_mics.end();
}

nlohmann::json ArrayErrors::to_json() const {
  nlohmann::json offsets = nlohmann::json::array();
  for (const auto& offset : mic_offset_m) offsets.push_back({offset.x(), offset.y(), offset.z()});
  nlohmann::json swapped = nlohmann::json::array();
  for (const auto& [a, b] : swapped_channels) swapped.push_back({a, b});
  return {{"mic_offset_m", offsets},
          {"channel_gain_db", channel_gain_db},
          {"channel_delay_s", channel_delay_s},
          {"yaw_deg", yaw_deg},
          {"pitch_deg", pitch_deg},
          {"roll_deg", roll_deg},
          {"clock_offset_s", clock_offset_s},
          {"dead_mics", dead_mics},
          {"flipped_mics", flipped_mics},
          {"swapped_channels", swapped}};
}

std::vector<ArrayErrors> draw_array_errors(const ArrayErrorSpec& spec,
                                           const config::SiteConfig& site) {
  std::vector<ArrayErrors> out(site.arrays.size());
  if (!spec.enabled) return out;
  for (std::size_t a = 0; a < site.arrays.size(); ++a) {
    // One stream per array, drawn in a fixed order: adding a key never changes the others' draws
    // of earlier keys.
    Random random(spec.seed, stream_id(kArrayErrors, a));
    ArrayErrors& errors = out[a];
    errors.yaw_deg = spec.yaw_std_deg * random.normal();
    errors.pitch_deg = spec.tilt_std_deg * random.normal();
    errors.roll_deg = spec.tilt_std_deg * random.normal();
    errors.clock_offset_s = spec.clock_offset_std_s * random.normal();
    for (std::size_t mic = 0; mic < site.arrays[a].geometry.mic_count(); ++mic) {
      const double x = random.normal(), y = random.normal(), z = random.normal();
      errors.mic_offset_m.push_back(spec.mic_position_std_m * Eigen::Vector3d(x, y, z));
      errors.channel_gain_db.push_back(spec.gain_spread_db * random.normal());
      errors.channel_delay_s.push_back(spec.channel_delay_std_s * random.normal());
    }
    for (const MicRef& ref : spec.channel_delays)
      if (ref.array_id == site.arrays[a].geometry.id)
        errors.channel_delay_s[static_cast<std::size_t>(ref.mic)] += ref.delay_s;
    for (const MicRef& ref : spec.dead_mics)
      if (ref.array_id == site.arrays[a].geometry.id) errors.dead_mics.push_back(ref.mic);
    for (const MicRef& ref : spec.flipped_mics)
      if (ref.array_id == site.arrays[a].geometry.id) errors.flipped_mics.push_back(ref.mic);
    for (const MicRef& ref : spec.swapped_channels)
      if (ref.array_id == site.arrays[a].geometry.id)
        errors.swapped_channels.push_back({ref.mic, ref.other_mic});
  }
  return out;
}

void apply_geometry_errors(const std::vector<ArrayErrors>& errors, config::SiteConfig& site) {
  for (std::size_t a = 0; a < site.arrays.size() && a < errors.size(); ++a) {
    doa::ArrayGeometry& geometry = site.arrays[a].geometry;
    geometry.yaw_deg += errors[a].yaw_deg;
    geometry.pitch_deg += errors[a].pitch_deg;
    geometry.roll_deg += errors[a].roll_deg;
    for (std::size_t mic = 0; mic < geometry.mic_count() && mic < errors[a].mic_offset_m.size();
         ++mic)
      geometry.mics_m[mic] += errors[a].mic_offset_m[mic];
  }
}

}  // namespace dronetrack::sim
