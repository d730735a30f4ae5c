#pragma once
// The evaluation report as a readable table and as JSON.
#include <string>

#include <nlohmann/json.hpp>

#include "eval/eval_data.hpp"

namespace dronetrack::eval {

std::string format_table(const EvalReport& report);
nlohmann::json to_json(const EvalReport& report);

}  // namespace dronetrack::eval
