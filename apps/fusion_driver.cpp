#include "apps/fusion_driver.hpp"

#include <algorithm>
#include <cmath>

namespace dronetrack::apps {
namespace {
// Tick times are multiples of the output period; k * 0.1 is not exact in binary.
constexpr double kTimeEpsilon_s = 1e-9;
}  // namespace

FusionDriver::FusionDriver(const config::SiteConfig& site, std::vector<FusionObserver*> observers)
    : engine_(site.fusion, site.geometries(), site.speed_of_sound_mps),
      zones_(site.zones, site.alerts),
      observers_(std::move(observers)),
      tracking_(
          std::any_of(observers_.begin(), observers_.end(),
                      [](const FusionObserver* observer) { return observer->wants_tracks(); })),
      output_period_s_(1.0 / site.fusion.output_rate_hz),
      reorder_window_s_(site.fusion.reorder_window_s) {}

fusion::DoaVerdict FusionDriver::on_doa(const doa::DoaMeasurement& doa) {
  const fusion::DoaVerdict verdict = tracking_ ? engine_.add(doa) : engine_.admit(doa);
  if (verdict == fusion::DoaVerdict::accepted) {
    for (auto* observer : observers_) observer->on_doa(doa);
  }
  return verdict;
}

void FusionDriver::on_node_status(const doa::NodeStatus& status) {
  for (auto* observer : observers_) observer->on_node_status(status);
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
  for (auto* observer : observers_) observer->on_time(now_s);
}

void FusionDriver::finish(double end_s) {
  if (!tracking_) return;
  if (first_tick_index_ < 0) first_tick_index_ = 0;  // nothing arrived: the one tick at 0
  const double last_s = std::isfinite(end_s) ? std::max(latest_time_s_, end_s) : latest_time_s_;
  while (next_tick_s_ <= last_s + kTimeEpsilon_s) emit_tick(next_tick_s_);
  engine_.advance_to(last_s + reorder_window_s_);
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
