#pragma once
// The fusion's bounds, in one place: the site config's "fusion" section is read into
// fusion::FusionParams and then checked here, and a program that fills FusionParams by hand
// (tests, benches) checks it with the same function. FusionEngine takes the params as checked.
#include <string>
#include <vector>

#include "fusion/fusion_params.hpp"

namespace dronetrack::config {

struct Diagnostics;

// Records every problem of `params` in `diagnostics`, each naming its JSON path below `path`
// ("fusion.confirm_hits: must be in [1, 1000], got 2000"). A rule between two keys is checked
// only once both are in their own bounds, so one mistake gives one line.
void check_fusion_params(const fusion::FusionParams& params, const std::string& path,
                         Diagnostics& diagnostics);

// The problems of hand-made params, as the site config would report them ("fusion.KEY: ...").
std::vector<std::string> fusion_params_problems(const fusion::FusionParams& params);

// Throws std::invalid_argument naming every problem (one per line) unless the params are valid.
void validate(const fusion::FusionParams& params);

}  // namespace dronetrack::config
