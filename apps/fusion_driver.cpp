#include "apps/fusion_driver.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/log.hpp"

namespace dronetrack::apps {
namespace {
// Tick times are multiples of the output period; k * 0.1 is not exact in binary.
constexpr double kTimeEpsilon_s = 1e-9;

std::string format(const char* pattern, double value) {
  char text[64];
  std::snprintf(text, sizeof text, pattern, value);
  return text;
}

// "channel 3", naming the input channel too when a channel_map moved the mic.
std::string channel_name(int mic, int input_channel) {
  std::string name = "channel " + std::to_string(mic);
  if (input_channel != mic) name += " (input channel " + std::to_string(input_channel) + ")";
  return name;
}

}  // namespace

std::string mirror_swap_warning(const std::string& array_id, int input_a, int input_b,
                                const fusion::MirrorSwapEvent& event) {
  return array_id + " " + channel_name(event.channel_a, input_a) + ": swapped with " +
         channel_name(event.channel_b, input_b) +
         " (seen by the fusion): its DOAs are the mirror image, through the plane between the two "
         "mics, of the tracks the other arrays fix (mean misfit " +
         format("%.1f", event.swapped_misfit_deg) + " deg mirrored against " +
         format("%.1f", event.wired_misfit_deg) + " deg as wired, over " +
         std::to_string(event.sectors) + " direction sectors) at " + format("%.2f", event.time_s) +
         " s; swap the two inputs or their channel_map entries";
}

FusionDriver::FusionDriver(const config::SiteConfig& site, std::vector<FusionObserver*> observers)
    : engine_(site.fusion, site.geometries(), site.speed_of_sound_mps),
      zones_(site.zones, site.alerts),
      observers_(std::move(observers)),
      tracking_(
          std::any_of(observers_.begin(), observers_.end(),
                      [](const FusionObserver* observer) { return observer->wants_tracks(); })),
      output_period_s_(1.0 / site.fusion.output_rate_hz),
      reorder_window_s_(site.fusion.reorder_window_s) {
  for (const auto& array : site.arrays) {
    array_ids_.push_back(array.geometry.id);
    channel_maps_.push_back(array.channel_map);
    swapped_seen_.emplace_back(array.geometry.mics_m.size(), doa::ArrayFlags{0});
  }
}

void FusionDriver::report_mirror_swaps() {
  mirror_events_.clear();
  engine_.take_mirror_events(mirror_events_);
  for (const fusion::MirrorSwapEvent& event : mirror_events_) {
    const auto array = static_cast<std::size_t>(event.array);
    const std::vector<int>& map = channel_maps_[array];
    const auto input_of = [&map](int mic) {
      return static_cast<std::size_t>(mic) < map.size() ? map[static_cast<std::size_t>(mic)] : mic;
    };
    log::warn(mirror_swap_warning(array_ids_[array], input_of(event.channel_a),
                                  input_of(event.channel_b), event));
    for (const int channel : {event.channel_a, event.channel_b}) {
      if (static_cast<std::size_t>(channel) < swapped_seen_[array].size())
        swapped_seen_[array][static_cast<std::size_t>(channel)] |=
            doa::array_flag(doa::ArrayProblem::swapped);
    }
  }
}

void FusionDriver::mark_fusion_findings(doa::NodeStatus& status) const {
  const auto found = std::find(array_ids_.begin(), array_ids_.end(), status.array_id);
  if (found == array_ids_.end()) return;
  const auto array = static_cast<std::size_t>(found - array_ids_.begin());
  const fusion::MirrorCheckStatus now = engine_.mirror_status(array);
  const auto swapped = doa::array_flag(doa::ArrayProblem::swapped);
  for (std::size_t c = 0; c < status.channels.size() && c < swapped_seen_[array].size(); ++c) {
    status.channels[c].array_problems_seen |= swapped_seen_[array][c];
    if (static_cast<int>(c) == now.swapped_a || static_cast<int>(c) == now.swapped_b)
      status.channels[c].array_problems |= swapped;
  }
}

fusion::DoaVerdict FusionDriver::on_doa(const doa::DoaMeasurement& doa) {
  const fusion::DoaVerdict verdict = tracking_ ? engine_.add(doa) : engine_.admit(doa);
  if (verdict == fusion::DoaVerdict::accepted) {
    for (auto* observer : observers_) observer->on_doa(doa);
  }
  return verdict;
}

void FusionDriver::on_node_status(const doa::NodeStatus& status) {
  doa::NodeStatus marked = status;
  mark_fusion_findings(marked);
  for (auto* observer : observers_) observer->on_node_status(marked);
}

void FusionDriver::advance_to(double now_s) {
  if (!std::isfinite(now_s) || now_s <= latest_time_s_) return;
  latest_time_s_ = now_s;
  if (!tracking_) {
    for (auto* observer : observers_) observer->on_time(now_s);
    return;
  }
  if (first_tick_index_ < 0) {
    first_tick_index_ = std::max<std::int64_t>(
        0, static_cast<std::int64_t>(std::floor((now_s - reorder_window_s_) / output_period_s_)));
    next_tick_s_ = static_cast<double>(first_tick_index_) * output_period_s_;
  }
  // A tick may only be reported once no DOA older than it can still arrive (reorder window),
  // and the engine is run exactly up to each tick so the report never predicts backwards.
  while (next_tick_s_ <= now_s - reorder_window_s_ + kTimeEpsilon_s) emit_tick(next_tick_s_);
  engine_.advance_to(now_s);
  report_mirror_swaps();
  for (auto* observer : observers_) observer->on_time(now_s);
}

void FusionDriver::finish(double heard_until_s) {
  if (!tracking_) return;
  if (first_tick_index_ < 0) first_tick_index_ = 0;  // nothing arrived: the one tick at 0
  if (std::isfinite(heard_until_s)) latest_time_s_ = std::max(latest_time_s_, heard_until_s);
  while (next_tick_s_ <= latest_time_s_ + kTimeEpsilon_s) emit_tick(next_tick_s_);
  engine_.advance_to(latest_time_s_ + reorder_window_s_);
  report_mirror_swaps();
}

void FusionDriver::emit_tick(double tick_s) {
  engine_.advance_to(tick_s + reorder_window_s_);  // feeds the DOAs older than the tick
  tracks_.clear();
  engine_.tracks_at(tick_s, tracks_);
  for (auto* observer : observers_) observer->on_tracks(tick_s, tracks_);
  zone_events_.clear();
  zones_.update(tick_s, tracks_, zone_events_);
  for (const auto& event : zone_events_) {
    for (auto* observer : observers_) observer->on_zone_event(event);
  }
  for (auto* observer : observers_) observer->on_counters(engine_.counters());
  ++ticks_emitted_;
  next_tick_s_ = static_cast<double>(first_tick_index_ + ticks_emitted_) * output_period_s_;
}

}  // namespace dronetrack::apps
