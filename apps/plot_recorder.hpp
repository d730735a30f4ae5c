#pragma once
// `replay --plot FILE`: keeps the run's track positions and DOAs as eval's records and, at the
// end, writes the figures without truth (plot/figures.hpp; docs/plots.md) atomically. Memory
// grows with the run (about 100 bytes a line): bounded at kMaxRecords of each, after which the
// page says the figures stop there.
#include <cstddef>
#include <string>
#include <vector>

#include "apps/fusion_observer.hpp"
#include "common/output_file.hpp"
#include "eval/eval_data.hpp"

namespace dronetrack::apps {

class PlotRecorder : public FusionObserver {
 public:
  static constexpr std::size_t kMaxRecords = 2'000'000;
  // Opens the output (OutputError on an unwritable path); nothing is in place until commit.
  PlotRecorder(const std::string& path, std::string title);
  void on_doa(const doa::DoaMeasurement& doa) override;
  void on_tracks(double time_s, const std::vector<fusion::TrackReport>& tracks) override;
  // Renders the page into the output; the caller commits it with the run's other outputs.
  void write();
  OutputFile& output() { return output_; }

 private:
  OutputFile output_;
  std::string title_;
  std::vector<eval::TrackRecord> tracks_;
  std::vector<eval::DoaRecord> doas_;
  bool truncated_ = false;
};

}  // namespace dronetrack::apps
