#pragma once
// The figures of `eval --plot` and `replay --plot` (docs/plots.md), built from the records eval
// reads (tracks, DOAs, truth) and the errors its matching computed, as Charts; and the one
// self-contained HTML page that holds them.
#include <string>
#include <vector>

#include "eval/eval_data.hpp"
#include "plot/svg_chart.hpp"

namespace dronetrack::plot {

// Plan view (x east / y north) and altitude over time of every track, each truth source dashed
// beside them when `truth` is given.
std::vector<Chart> track_charts(const std::vector<eval::TrackRecord>& tracks,
                                const eval::Truth* truth);
// 3-D error over time of the tracks assigned to each source, one series per (source, track).
Chart error_chart(const eval::EvalReport& report);
// DOA angular error over time, one series per array.
Chart doa_error_chart(const eval::EvalReport& report);
// Without truth: azimuth and elevation of every DOA over time, one series per array.
std::vector<Chart> doa_charts(const std::vector<eval::DoaRecord>& doas);

// <!DOCTYPE html> page: the title, the lines of `notes`, then one inline SVG per chart.
std::string html_page(const std::string& title, const std::vector<std::string>& notes,
                      const std::vector<Chart>& charts);

}  // namespace dronetrack::plot
