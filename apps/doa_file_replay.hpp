#pragma once
// `replay --doa-in D.jsonl`: the fusion alone, on DOAs an earlier replay wrote (or any tool
// writing SPEC 3.2 DOA lines), through the same FusionDriver as the full replay. Tuning the
// fusion on a long recording then takes seconds instead of re-running every array's DSP.
#include <atomic>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "apps/fusion_observer.hpp"
#include "apps/replay_runner.hpp"
#include "config/site_config.hpp"
#include "doa/doa_measurement.hpp"

namespace dronetrack::apps {

// A DOA file spans at most this much time (first to last DOA); see read_doa_measurements.
inline constexpr double kMaxDoaSpan_s = 86400.0;

// The file's DOA lines as measurements of this site, in time order. Lines without azel_std_deg
// (SPEC 3.2's minimal line) get `default_std_deg` on both angles. Throws std::runtime_error,
// one line naming the file and the line or DOA at fault (an array the site does not have).
std::vector<doa::DoaMeasurement> read_doa_measurements(const std::filesystem::path& file,
                                                       const config::SiteConfig& site,
                                                       double default_std_deg = 0.5);

// Feeds the DOAs (time order) to a FusionDriver with these observers, as the replay would, and
// reports the tracks up to audio_end_s (the end of the audio the DOAs were made from) or, when
// it is not finite, up to the last DOA: a DOA file alone does not say when its audio ended.
ReplaySummary replay_doas(const config::SiteConfig& site,
                          const std::vector<doa::DoaMeasurement>& doas,
                          const std::vector<FusionObserver*>& observers,
                          const std::atomic<bool>* stop = nullptr,
                          double audio_end_s = std::numeric_limits<double>::quiet_NaN());

// "" when audio_end_s can end a replay of these DOAs (time order), else the problem, naming
// the option: before the last DOA, or more than kMaxDoaSpan_s after the first.
std::string audio_end_problem(const std::vector<doa::DoaMeasurement>& doas, double audio_end_s);

}  // namespace dronetrack::apps
