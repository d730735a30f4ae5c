#pragma once
// The end of a command's run decides what its outputs become (docs/contract.md): committed when
// the run completed, kept as TARGET.partial with a non-zero exit when a signal stopped it or an
// input was cut short. One place, so every subcommand follows the same policy.
#include <string>
#include <vector>

#include "common/output_file.hpp"
#include "config/site_config.hpp"

namespace dronetrack::apps {

class RunOutputs {
 public:
  void add(OutputFile& file) { files_.push_back(&file); }
  // Completed (no stop signal, `cut_short` empty): commits every output and returns 0 (throws
  // OutputError if a commit fails). Otherwise keeps each output as partial, logs one error line
  // saying why and where the partial results are, and returns 128 + signal (interrupted) or 1.
  int finish(const std::string& command, const std::string& cut_short = "");

 private:
  std::vector<OutputFile*> files_;
};

// The files a site config makes a command read: the config itself and, when `recordings`, every
// array's recording.
std::vector<NamedPath> site_inputs(const config::SiteConfig& site, bool recordings);

}  // namespace dronetrack::apps
