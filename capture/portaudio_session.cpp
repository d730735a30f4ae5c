#include "capture/portaudio_session.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <stdexcept>
#include <string>

#include <portaudio.h>

#include "common/log.hpp"

namespace dronetrack::capture {
namespace {

// PortAudio's host APIs probe by trial: ALSA prints dozens of "cannot find card '0'" lines on a
// machine without a sound card and JACK complains that no server runs, all straight to
// stderr. None of it is actionable, and it buries our own one-line errors, so it is hidden
// while PortAudio starts and stops, unless the log level is debug. Other threads' stderr lines
// written in that instant are lost too; PortAudio starts before the pipeline runs.
class QuietStderr {
 public:
  QuietStderr() {
    if (log::level() <= log::Level::debug) return;
    std::fflush(stderr);
    saved_ = ::dup(STDERR_FILENO);
    const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (saved_ < 0 || null < 0 || ::dup2(null, STDERR_FILENO) < 0) {
      if (null >= 0) ::close(null);
      restore();
      return;
    }
    ::close(null);
  }
  ~QuietStderr() { restore(); }
  QuietStderr(const QuietStderr&) = delete;
  QuietStderr& operator=(const QuietStderr&) = delete;

 private:
  void restore() {
    if (saved_ < 0) return;
    std::fflush(stderr);
    ::dup2(saved_, STDERR_FILENO);
    ::close(saved_);
    saved_ = -1;
  }
  int saved_ = -1;
};

}  // namespace

PortAudioSession::PortAudioSession() {
  PaError error = paNoError;
  {
    const QuietStderr quiet;
    error = Pa_Initialize();
  }
  if (error != paNoError) {
    // A failed Pa_Initialize leaves nothing to terminate.
    throw std::runtime_error(std::string("PortAudio: cannot initialise (") +
                             Pa_GetErrorText(error) + ")");
  }
}

PortAudioSession::~PortAudioSession() {
  const QuietStderr quiet;
  Pa_Terminate();
}

}  // namespace dronetrack::capture
