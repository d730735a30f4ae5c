#pragma once
// Where the executable finds its read-only files (the web page, the bundled scenarios).
#include <filesystem>
#include <string_view>

namespace dronetrack::apps {

// The first of these that exists, else the last:
//  1. beside the install prefix the running executable sits in: PREFIX/bin/dronetrack ->
//     PREFIX/share/dronetrack/`installed` (the .deb: /usr/share/dronetrack/...; also a package
//     unpacked anywhere, or `cmake --install --prefix DIR`). First, so an installed copy never
//     serves the files of a source tree that happens to be on the same machine;
//  2. the source tree this binary was built from: `in_source` under it (a build tree's binary).
std::filesystem::path data_path(std::string_view installed, std::string_view in_source);

// PREFIX/share/dronetrack for the running executable (/proc/self/exe); empty if unknown.
std::filesystem::path installed_data_dir();

}  // namespace dronetrack::apps
