#pragma once
// Every whole text file a command reads (site config, scenario, users file, truth): bounded
// before it is held in memory, one error naming the file. The estimation code never reads files;
// the edges (config, sim, eval, http_api, apps) do.
#include <cstddef>
#include <filesystem>
#include <string>

namespace dronetrack {

// The whole file as text; throws std::runtime_error "FILE: ..." if it cannot be read or is
// larger than `max_bytes` (`what` names the kind of file in that message).
std::string read_text_file(const std::filesystem::path& file, std::size_t max_bytes,
                           const std::string& what);

}  // namespace dronetrack
