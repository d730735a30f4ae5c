#pragma once
// What real arrays get wrong (issue 16), drawn per array from the scenario's "array_errors" keys
// (docs/scenarios.md): mics a few millimetres off their nominal positions, channels that differ
// in gain and delay, a yaw set by compass to a degree or two, a tilted mast, a node clock that is
// milliseconds off. The scene is rendered with the arrays as drawn; site.json keeps the nominal
// values (what the operator believes), truth.json records the draws.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "config/site_config.hpp"

namespace dronetrack::sim {

// One mic of one array (array_errors.dead_mics, flipped_mics, channel_delays), or two
// (swapped_channels).
struct MicRef {
  std::string array_id;
  int mic = 0;
  int other_mic = -1;    // swapped_channels: the mic whose channel `mic`'s is swapped with
  double delay_s = 0.0;  // channel_delays: how late channel `mic` records
};

// The keys, each a 1-sigma spread (0: none), and the faults set by name.
struct ArrayErrorSpec {
  bool enabled = false;
  std::uint64_t seed = 0;                  // draws; default the scenario's seed
  double mic_position_std_m = 0.0;         // each mic coordinate, array frame
  double gain_spread_db = 0.0;             // each channel's gain
  double channel_delay_std_s = 0.0;        // each channel's delay (channel 0 included)
  double yaw_std_deg = 0.0;                // the array's yaw
  double tilt_std_deg = 0.0;               // its pitch and its roll
  double clock_offset_std_s = 0.0;         // the node's clock: its recording starts this late
  std::vector<MicRef> dead_mics{};         // record their sensor noise only (no sound reaches them)
  std::vector<MicRef> flipped_mics{};      // record everything inverted (polarity flipped)
  std::vector<MicRef> swapped_channels{};  // two mics wired to each other's channel
  std::vector<MicRef> channel_delays{};    // one channel's fixed delay, on top of the drawn one
};

// One array's draws.
struct ArrayErrors {
  std::vector<Eigen::Vector3d> mic_offset_m;  // array frame, per mic
  std::vector<double> channel_gain_db;        // per mic
  std::vector<double> channel_delay_s;        // per mic
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
  double clock_offset_s = 0.0;
  std::vector<int> dead_mics{};     // mic indices
  std::vector<int> flipped_mics{};  // mic indices
  std::vector<std::array<int, 2>>
      swapped_channels{};  // mic index pairs, each recorded on the other's channel
  bool dead(std::size_t mic) const;
  bool flipped(std::size_t mic) const;
  // How late channel `mic` records the sound that reaches the mic at t: clock + channel delay.
  double recording_delay_s(std::size_t mic) const;
  double gain(std::size_t mic) const;  // linear
  nlohmann::json to_json() const;
};

// Per array of `site`, deterministic in spec.seed and the array's index; the dead and flipped
// mics as listed (their arrays and indices checked by the scenario parser).
std::vector<ArrayErrors> draw_array_errors(const ArrayErrorSpec& spec,
                                           const config::SiteConfig& site);
// The arrays as they really are: mics, yaw, pitch and roll with the draws applied.
void apply_geometry_errors(const std::vector<ArrayErrors>& errors, config::SiteConfig& site);

}  // namespace dronetrack::sim
