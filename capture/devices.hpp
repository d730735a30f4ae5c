#pragma once
// The audio input devices PortAudio can see, for `dronetrack devices` and for error messages.
#include <string>
#include <vector>

namespace dronetrack::capture {

struct DeviceInfo {
  int index = -1;  // PortAudio device index, as `--device` takes it
  std::string name;
  std::string host_api;  // e.g. "ALSA", "JACK Audio Connection Kit"
  int max_input_channels = 0;
  double default_sample_rate_hz = 0.0;
  bool is_default_input = false;
};

// Devices with at least one input channel, in PortAudio's index order. Throws
// std::runtime_error "PortAudio: <why>" if the library cannot start.
std::vector<DeviceInfo> list_input_devices();

}  // namespace dronetrack::capture
