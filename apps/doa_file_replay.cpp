#include "apps/doa_file_replay.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "apps/commands.hpp"
#include "apps/fusion_driver.hpp"
#include "common/log.hpp"
#include "config/config_reader.hpp"
#include "doa/array_geometry.hpp"
#include "eval/readers.hpp"

namespace dronetrack::apps {
namespace {

doa::DoaAmbiguity ambiguity_of(const std::string& name) {
  if (name == "mirror_up_down") return doa::DoaAmbiguity::mirror_up_down;
  if (name == "cone") return doa::DoaAmbiguity::cone;
  return doa::DoaAmbiguity::none;
}

// The line's pose (a moving array), or the site's fixed one; the cone or mirror plane.
void copy_geometry(const eval::DoaRecord& record, const doa::ArrayGeometry& geometry,
                   doa::DoaMeasurement& doa) {
  constexpr double kRadPerDeg = std::numbers::pi / 180.0;
  if (record.pose) {
    const Eigen::Vector3d& attitude = record.pose->attitude_deg;
    doa.pose = {record.pose->centre_m,
                Eigen::Quaterniond(doa::attitude_to_site(attitude(0), attitude(1), attitude(2))),
                true};
  } else {
    doa.pose = {geometry.centre_site_m(), Eigen::Quaterniond(geometry.array_to_site()), false};
  }
  if (record.cone) {
    doa.ambiguity_axis = record.cone->axis;
    doa.cone_angle_rad = record.cone->angle_deg * kRadPerDeg;
    const double std_rad = record.cone->angle_std_deg * kRadPerDeg;
    doa.cone_angle_variance_rad2 = std_rad * std_rad;
    doa.cone_peak_count = static_cast<int>(record.cone->peaks_deg.size());
    for (int k = 0; k < doa.cone_peak_count; ++k) {
      doa.cone_peak_angle_rad[static_cast<std::size_t>(k)] =
          record.cone->peaks_deg[static_cast<std::size_t>(k)] * kRadPerDeg;
      doa.cone_peak_weight[static_cast<std::size_t>(k)] =
          record.cone->peak_weights[static_cast<std::size_t>(k)];
    }
  }
  if (record.mirror_normal) doa.ambiguity_axis = *record.mirror_normal;
}

std::string site_array_ids(const config::SiteConfig& site) {
  std::string ids;
  for (const auto& array : site.arrays) ids += (ids.empty() ? "" : ", ") + array.geometry.id;
  return ids;
}

}  // namespace

std::vector<doa::DoaMeasurement> read_doa_measurements(const std::filesystem::path& file,
                                                       const config::SiteConfig& site,
                                                       double default_std_deg) {
  std::vector<eval::DoaRecord> records;
  try {
    records = eval::read_doas(file);
  } catch (const eval::InputError& error) {
    throw UserError(error.what());
  }
  // The fusion ticks through every output period between the first DOA and the last: bound
  // the span so one stray time cannot mean billions of ticks.
  double first_s = std::numeric_limits<double>::infinity();
  for (const eval::DoaRecord& record : records) first_s = std::min(first_s, record.time_s);
  for (const eval::DoaRecord& record : records) {
    if (record.time_s - first_s > kMaxDoaSpan_s) {
      throw UserError(file.string() + ":" + std::to_string(record.line) + ": t " +
                      config::format_number(record.time_s) + " s is " +
                      config::format_number(record.time_s - first_s) +
                      " s after the file's first DOA; one replay spans at most " +
                      config::format_number(kMaxDoaSpan_s) + " s (24 h)");
    }
  }
  std::vector<doa::DoaMeasurement> doas;
  doas.reserve(records.size());
  std::size_t without_std = 0;
  constexpr double kRadPerDeg = std::numbers::pi / 180.0;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const eval::DoaRecord& record = records[i];
    doa::DoaMeasurement doa;
    doa.array_id = record.array;
    doa.array_index = site.array_index(record.array);
    if (doa.array_index < 0) {
      throw std::runtime_error(file.string() + ": DOA " + std::to_string(i + 1) + " (t " +
                               std::to_string(record.time_s) + " s): array '" +
                               config::printable(record.array) + "' is not in the site (" +
                               site_array_ids(site) + ")");
    }
    doa.time_s = record.time_s;
    doa.direction = record.direction.normalized();
    doa.quality = record.quality;
    doa.snr_db = record.snr_db;
    doa.source_index = record.source_index;
    doa.ambiguity = ambiguity_of(record.ambiguity);
    doa.acoustic = record.acoustic;
    const Eigen::Vector2d std_rad =
        record.azel_std_deg.value_or(Eigen::Vector2d::Constant(default_std_deg)) * kRadPerDeg;
    const double covariance = record.azel_correlation * std_rad(0) * std_rad(1);
    doa.azel_covariance_rad2 << std_rad(0) * std_rad(0), covariance, covariance,
        std_rad(1) * std_rad(1);
    copy_geometry(record, site.arrays[static_cast<std::size_t>(doa.array_index)].geometry, doa);
    without_std += record.azel_std_deg ? 0 : 1;
    doas.push_back(std::move(doa));
  }
  if (without_std > 0) {
    log::warn(file.string(), ": ", without_std, " DOAs without azel_std_deg, taken as ",
              default_std_deg, " deg");
  }
  std::stable_sort(doas.begin(), doas.end(),
                   [](const doa::DoaMeasurement& a, const doa::DoaMeasurement& b) {
                     return a.time_s < b.time_s;
                   });
  return doas;
}

ReplaySummary replay_doas(const config::SiteConfig& site,
                          const std::vector<doa::DoaMeasurement>& doas,
                          const std::vector<FusionObserver*>& observers,
                          const std::atomic<bool>* stop, double audio_end_s) {
  const auto wall_start = std::chrono::steady_clock::now();
  FusionDriver driver(site, observers);
  ReplaySummary summary;
  for (const doa::DoaMeasurement& doa : doas) {
    if (stop && stop->load()) break;
    // Every DOA older than this one is in: the fusion may run up to its time, as the replay
    // runs it up to the slowest node's.
    driver.advance_to(doa.time_s);
    ++summary.doas;
    if (driver.on_doa(doa) == fusion::DoaVerdict::accepted) ++summary.doas_accepted;
    if (std::isfinite(doa.time_s)) summary.stream_s = std::max(summary.stream_s, doa.time_s);
  }
  driver.finish(audio_end_s);
  if (std::isfinite(audio_end_s)) summary.stream_s = std::max(summary.stream_s, audio_end_s);
  summary.ticks = driver.ticks_emitted();
  summary.counters = driver.engine().counters();
  // Only an estimate is news: a fixed e is the config's.
  if (site.fusion.likelihood == fusion::DoaLikelihoodKind::outlier_mixture &&
      site.fusion.adaptive_outlier_probability) {
    std::string shares;
    for (std::size_t a = 0; a < driver.engine().arrays().size(); ++a)
      shares += (a ? " " : "") + std::to_string(driver.engine().outlier_share(a));
    log::info("fusion: outlier share e per array at the end: ", shares);
  }
  summary.wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return summary;
}

std::string audio_end_problem(const std::vector<doa::DoaMeasurement>& doas, double audio_end_s) {
  if (!std::isfinite(audio_end_s) || doas.empty()) return "";
  const std::string option = "--audio-end-s " + config::format_number(audio_end_s);
  // The DOAs are in time order: the first and last are the file's span.
  if (audio_end_s < doas.back().time_s) {
    return option + " is before the last DOA (t " + config::format_number(doas.back().time_s) +
           " s): the audio cannot end before a DOA made from it";
  }
  if (audio_end_s - doas.front().time_s > kMaxDoaSpan_s) {
    return option + " is " + config::format_number(audio_end_s - doas.front().time_s) +
           " s after the first DOA; one replay spans at most " +
           config::format_number(kMaxDoaSpan_s) + " s (24 h)";
  }
  return "";
}

}  // namespace dronetrack::apps
