#pragma once
// Readers of the files eval compares: truth.json (SPEC 3.2b) and the JSON-lines DOAs and tracks
// (SPEC 3.2). Every problem is one line naming the file and where: "T.jsonl:12: position_m:
// expected 3 numbers, got 2" or "truth.json: sources[0].t: must be increasing".
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "eval/eval_data.hpp"

namespace dronetrack::eval {

struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Times in DOA, track and alert lines: seconds of stream time, or of any clock a tool uses (UNIX
// time is 1.8e9); beyond 1e10 a double no longer resolves a microsecond and the value is a bug.
inline constexpr double kMaxAbsoluteTime_s = 1e10;

Truth read_truth(const std::filesystem::path& file);
std::vector<TrackRecord> read_tracks(const std::filesystem::path& file);
std::vector<DoaRecord> read_doas(const std::filesystem::path& file);

// The same from text (file is only used in messages).
Truth parse_truth(const std::string& text, const std::string& file);
std::vector<TrackRecord> parse_tracks(const std::string& text, const std::string& file);
std::vector<DoaRecord> parse_doas(const std::string& text, const std::string& file);
// `replay --alerts-out` lines.
std::vector<AlertRecord> read_alerts(const std::filesystem::path& file);
std::vector<AlertRecord> parse_alerts(const std::string& text, const std::string& file);

}  // namespace dronetrack::eval
