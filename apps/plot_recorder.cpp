#include "apps/plot_recorder.hpp"

#include <utility>

#include "plot/figures.hpp"

namespace dronetrack::apps {

PlotRecorder::PlotRecorder(const std::string& path, std::string title)
    : output_(path), title_(std::move(title)) {}

void PlotRecorder::on_doa(const doa::DoaMeasurement& doa) {
  if (doas_.size() >= kMaxRecords) {
    truncated_ = true;
    return;
  }
  eval::DoaRecord record;
  record.time_s = doa.time_s;
  record.array = doa.array_id;
  record.direction = doa.direction;
  record.source_index = doa.source_index;
  doas_.push_back(std::move(record));
}

void PlotRecorder::on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) {
  for (const auto& track : tracks) {
    if (tracks_.size() >= kMaxRecords) {
      truncated_ = true;
      return;
    }
    eval::TrackRecord record;
    record.time_s = time_s;
    record.id = track.id;
    record.position_m = track.position_m;
    tracks_.push_back(record);
  }
}

void PlotRecorder::write() {
  std::vector<plot::Chart> charts = plot::track_charts(tracks_, nullptr);
  for (auto& chart : plot::doa_charts(doas_)) charts.push_back(std::move(chart));
  // append, not operator+ chains: GCC 12 warns falsely (-Warray-bounds) on those.
  std::string summary = std::to_string(tracks_.size());
  summary.append(" track positions, ")
      .append(std::to_string(doas_.size()))
      .append(" DOAs; no truth");
  std::vector<std::string> notes = {summary};
  if (truncated_) {
    std::string note = "The run was longer than the plot keeps (";
    note.append(std::to_string(kMaxRecords)).append(" records of each): the figures stop there.");
    notes.push_back(note);
  }
  output_.write(plot::html_page(title_, notes, charts));
}

}  // namespace dronetrack::apps
