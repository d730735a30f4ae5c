// `dronetrack devices`: the audio input devices PortAudio sees, with the index `node --device`
// takes, so an operator can check that the array's interface has enough channels.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "apps/commands.hpp"
#include "capture/devices.hpp"

namespace dronetrack::apps {
namespace {

void print_table(const std::vector<capture::DeviceInfo>& devices) {
  if (devices.empty()) {
    std::cout << "no audio input devices found (PortAudio sees no capture device)\n";
    return;
  }
  std::size_t name_width = 4;
  std::size_t host_width = 8;
  for (const auto& device : devices) {
    name_width = std::max(name_width, device.name.size());
    host_width = std::max(host_width, device.host_api.size());
  }
  std::printf("%5s  %-*s  %-*s  %8s  %12s\n", "index", static_cast<int>(name_width), "name",
              static_cast<int>(host_width), "host api", "channels", "default rate");
  for (const auto& device : devices) {
    std::printf("%4d%c  %-*s  %-*s  %8d  %9.0f Hz\n", device.index,
                device.is_default_input ? '*' : ' ', static_cast<int>(name_width),
                device.name.c_str(), static_cast<int>(host_width), device.host_api.c_str(),
                device.max_input_channels, device.default_sample_rate_hz);
  }
  std::printf("(* = default input; channels = maximum input channels)\n");
}

void print_json_lines(const std::vector<capture::DeviceInfo>& devices) {
  for (const auto& device : devices) {
    const nlohmann::json line = {{"index", device.index},
                                 {"name", device.name},
                                 {"host_api", device.host_api},
                                 {"max_input_channels", device.max_input_channels},
                                 {"default_sample_rate_hz", device.default_sample_rate_hz},
                                 {"default_input", device.is_default_input}};
    std::cout << line.dump() << '\n';
  }
}

}  // namespace

void register_devices(CLI::App& root, CommandTable& table) {
  auto* command = root.add_subcommand(
      "devices", "List audio input devices (index, name, host API, input channels, rate)");
  auto json = std::make_shared<bool>(false);
  command->add_flag("--json", *json, "One JSON object per device and line instead of a table");
  table.add(command, [json]() -> int {
    const std::vector<capture::DeviceInfo> devices = capture::list_input_devices();
    if (*json) {
      print_json_lines(devices);
    } else {
      print_table(devices);
    }
    return 0;
  });
}

}  // namespace dronetrack::apps
