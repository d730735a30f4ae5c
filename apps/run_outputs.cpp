#include "apps/run_outputs.hpp"

#include "apps/signals.hpp"
#include "common/log.hpp"

namespace dronetrack::apps {

int RunOutputs::finish(const std::string& command, const std::string& cut_short) {
  if (!stop_requested() && cut_short.empty()) {
    for (OutputFile* file : files_) file->commit();
    return 0;
  }
  std::string kept;
  for (OutputFile* file : files_) {
    const bool to_stdout = file->is_stdout();
    const std::filesystem::path where = file->keep_partial();
    if (to_stdout) continue;
    kept += (kept.empty() ? "" : ", ") + where.string();
  }
  const std::string why =
      stop_requested() ? std::string("interrupted by ") + stop_signal_name() : cut_short;
  log::error(command, ": ", why, kept.empty() ? "" : "; partial results kept in ", kept);
  return stop_requested() ? interrupted_exit_code() : 1;
}

std::vector<NamedPath> site_inputs(const config::SiteConfig& site, bool recordings) {
  std::vector<NamedPath> inputs{{"the site config", site.file}};
  if (!recordings) return inputs;
  for (std::size_t i = 0; i < site.arrays.size(); ++i) {
    if (!site.arrays[i].recording.empty())
      inputs.push_back({"arrays[" + std::to_string(i) + "].recording", site.arrays[i].recording});
    if (!site.arrays[i].pose_file.empty())
      inputs.push_back({"arrays[" + std::to_string(i) + "].pose_file", site.arrays[i].pose_file});
  }
  return inputs;
}

}  // namespace dronetrack::apps
