#include "capture/recording_info.hpp"

#include <stdexcept>

#include <sndfile.h>

namespace dronetrack::capture {
namespace {
std::string describe_format(int format) {
  std::string container;
  switch (format & SF_FORMAT_TYPEMASK) {
    case SF_FORMAT_WAV:
      container = "WAV";
      break;
    case SF_FORMAT_WAVEX:
      container = "WAVEX";
      break;
    case SF_FORMAT_FLAC:
      container = "FLAC";
      break;
    case SF_FORMAT_AIFF:
      container = "AIFF";
      break;
    case SF_FORMAT_W64:
      container = "W64";
      break;
    case SF_FORMAT_RF64:
      container = "RF64";
      break;
    default:
      container = "other";
      break;
  }
  std::string encoding;
  switch (format & SF_FORMAT_SUBMASK) {
    case SF_FORMAT_PCM_16:
      encoding = "PCM16";
      break;
    case SF_FORMAT_PCM_24:
      encoding = "PCM24";
      break;
    case SF_FORMAT_PCM_32:
      encoding = "PCM32";
      break;
    case SF_FORMAT_FLOAT:
      encoding = "float32";
      break;
    case SF_FORMAT_DOUBLE:
      encoding = "float64";
      break;
    default:
      encoding = "other";
      break;
  }
  return container + " " + encoding;
}
}  // namespace

RecordingInfo probe_recording(const std::filesystem::path& file) {
  std::error_code error;
  if (!std::filesystem::exists(file, error)) {
    throw std::runtime_error(file.string() + ": recording not found");
  }
  SF_INFO info{};
  SNDFILE* handle = sf_open(file.c_str(), SFM_READ, &info);
  if (!handle) {
    throw std::runtime_error(file.string() + ": cannot read as audio (" + sf_strerror(nullptr) +
                             ")");
  }
  sf_close(handle);
  RecordingInfo out;
  out.channels = info.channels;
  out.sample_rate_hz = info.samplerate;
  out.frames = info.frames;
  out.format = describe_format(info.format);
  return out;
}

}  // namespace dronetrack::capture
