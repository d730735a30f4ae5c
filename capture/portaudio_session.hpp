#pragma once
// RAII for PortAudio's library state: Pa_Initialize on construction, Pa_Terminate on
// destruction. PortAudio counts nested initialisations, so sessions may overlap (a device
// listing while a stream is open); each one must outlive the streams opened under it.
namespace dronetrack::capture {

class PortAudioSession {
 public:
  // Throws std::runtime_error "PortAudio: <why>" if the library cannot start.
  PortAudioSession();
  ~PortAudioSession();
  PortAudioSession(const PortAudioSession&) = delete;
  PortAudioSession& operator=(const PortAudioSession&) = delete;
};

}  // namespace dronetrack::capture
