#pragma once
// Numeric option checks for every subcommand. CLI11's NonNegativeNumber and PositiveNumber
// accept "nan" and "inf" (NaN compares false with everything), which then reach a loop bound or
// a timer; these refuse anything not finite, and give each option a range with a reason.
#include <cmath>
#include <string>

#include <CLI/CLI.hpp>

#include "config/config_reader.hpp"
#include "http_api/bind_address.hpp"

namespace dronetrack::apps {

// A finite number in [min, max]; a description like "a duration in seconds" goes in the error.
inline CLI::Validator finite_in(double min, double max) {
  return CLI::Validator(
      [min, max](std::string& text) -> std::string {
        double value = 0.0;
        if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value))
          return "expected a finite number, got " + text;
        if (value < min || value > max) {
          return "expected a number in [" + config::format_number(min) + ", " +
                 config::format_number(max) + "], got " + text;
        }
        return std::string();
      },
      "FINITE in [" + config::format_number(min) + ", " + config::format_number(max) + "]");
}

// HOST:PORT for --http, checked when the command line is parsed (a bad one exits 2).
inline CLI::Validator http_address() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        try {
          http_api::parse_bind_address(text);
        } catch (const std::exception& error) {
          return error.what();
        }
        return std::string();
      },
      "HOST:PORT");
}

// Durations a run may be given: up to a year of stream or wall time.
inline constexpr double kMaxDuration_s = 365.0 * 86400.0;

}  // namespace dronetrack::apps
