#pragma once
// The evaluation's arithmetic (SPEC 4.7), pure: truth and records in, report out.
//
// Tracks are compared with the truth on a grid of ticks (the tracks' output interval unless
// given). At each tick, the counted tracks (confirmed and coasting; tentative only on request)
// are assigned to the live truth sources by an optimal assignment (Hungarian) on 3-D distance,
// pairs farther than association_gate_m forbidden. Position errors use every associated pair;
// a source is covered at a tick when its associated track is within coverage_gate_m; an id
// switch is a change of the track id associated with a source; false-track time is track time
// associated with no source.
#include <vector>

#include "eval/eval_data.hpp"

namespace dronetrack::eval {

// The most evaluation steps one run may take (a 24 h truth at 10 ms); more throws InputError.
inline constexpr double kMaxEvalSteps = 1e7;

//
// Drone or not (issue 14): a counted track assigned to no drone at a tick follows the nearest
// other truth source within the association gate, widened to 5 % of that source's distance from
// the array centroid (an aircraft at 300 m is fixed to a few per cent of its range); its class at
// that tick is what the class figures count. With alerts, each zone entry is a drone's when its
// track follows a drone at the nearest tick.
EvalReport evaluate(const Truth& truth, const std::vector<TrackRecord>& tracks,
                    const std::vector<DoaRecord>& doas, const EvalOptions& options,
                    const std::vector<AlertRecord>* alerts = nullptr);

// DOA angular error per array: each DOA against the truth direction of the nearest source.
std::vector<DoaArrayMetrics> doa_errors(const Truth& truth, const std::vector<DoaRecord>& doas,
                                        int* unmatched = nullptr);

}  // namespace dronetrack::eval
