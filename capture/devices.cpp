#include "capture/devices.hpp"

#include <portaudio.h>

#include "capture/portaudio_session.hpp"

namespace dronetrack::capture {

std::vector<DeviceInfo> list_input_devices() {
  const PortAudioSession session;
  std::vector<DeviceInfo> devices;
  const PaDeviceIndex count = Pa_GetDeviceCount();
  const PaDeviceIndex default_input = Pa_GetDefaultInputDevice();
  for (PaDeviceIndex index = 0; index < count; ++index) {
    const PaDeviceInfo* info = Pa_GetDeviceInfo(index);
    if (info == nullptr || info->maxInputChannels <= 0) continue;
    DeviceInfo device;
    device.index = index;
    device.name = info->name != nullptr ? info->name : "";
    const PaHostApiInfo* host = Pa_GetHostApiInfo(info->hostApi);
    device.host_api = host != nullptr && host->name != nullptr ? host->name : "";
    device.max_input_channels = info->maxInputChannels;
    device.default_sample_rate_hz = info->defaultSampleRate;
    device.is_default_input = index == default_input;
    devices.push_back(std::move(device));
  }
  return devices;
}

}  // namespace dronetrack::capture
