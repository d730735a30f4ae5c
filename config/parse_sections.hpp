#pragma once
// Section parsers of the site config, one file each, so the module that owns the parameters
// owns the keys: parse_doa_params.cpp (doa/), parse_fusion_params.cpp (fusion/).
#include "config/config_reader.hpp"
#include "doa/doa_params.hpp"
#include "fusion/fusion_params.hpp"

namespace dronetrack::config {

// Fill `params` from the "doa" object; absent keys keep their defaults.
void parse_doa_params(ObjectReader& section, doa::DoaParams& params);
// Fill `params` from the "fusion" object.
void parse_fusion_params(ObjectReader& section, fusion::FusionParams& params);

}  // namespace dronetrack::config
