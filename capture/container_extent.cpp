#include "capture/container_extent.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <fstream>

namespace dronetrack::capture {
namespace {

// A file read at absolute offsets; a read past its end fails.
class Bytes {
 public:
  explicit Bytes(const std::filesystem::path& file) : in_(file, std::ios::binary) {
    std::error_code error;
    size_ = static_cast<std::int64_t>(std::filesystem::file_size(file, error));
    if (error) size_ = -1;
  }
  bool ok() const { return in_.good() && size_ >= 0; }
  std::int64_t size() const { return size_; }
  template <std::size_t N>
  bool read(std::int64_t offset, std::array<unsigned char, N>& out) {
    if (offset < 0 || offset + static_cast<std::int64_t>(N) > size_) return false;
    in_.seekg(offset);
    return static_cast<bool>(in_.read(reinterpret_cast<char*>(out.data()), N));
  }

 private:
  std::ifstream in_;
  std::int64_t size_ = -1;
};

std::uint64_t unsigned_of(const unsigned char* bytes, int count, bool big_endian) {
  std::uint64_t value = 0;
  for (int i = 0; i < count; ++i) {
    const int index = big_endian ? i : count - 1 - i;
    value = (value << 8) | bytes[index];
  }
  return value;
}

bool tag_is(const unsigned char* bytes, const char* tag) { return std::memcmp(bytes, tag, 4) == 0; }

// The audio data starts at `data_start`, the header declares `declared_bytes` of it.
std::optional<DataExtent> extent(const char* container, std::int64_t file_size,
                                 std::int64_t data_start, std::int64_t declared_bytes,
                                 int bytes_per_frame) {
  if (declared_bytes <= 0) return std::nullopt;
  const std::int64_t present_bytes =
      std::clamp<std::int64_t>(file_size - data_start, 0, declared_bytes);
  return DataExtent{container, declared_bytes / bytes_per_frame, present_bytes / bytes_per_frame};
}

// RIFF/RIFX WAVE: chunks of id + 32-bit size, word aligned; RF64/BW64 put the 64-bit data size
// in a ds64 chunk and 0xFFFFFFFF in the data chunk's size.
std::optional<DataExtent> riff(Bytes& bytes, const std::array<unsigned char, 12>& head,
                               int bytes_per_frame) {
  const bool rf64 = tag_is(head.data(), "RF64") || tag_is(head.data(), "BW64");
  const bool big_endian = tag_is(head.data(), "RIFX");
  const char* container = rf64 ? "RF64" : big_endian ? "RIFX WAV" : "RIFF WAV";
  std::uint64_t ds64_data_size = 0;
  std::int64_t offset = 12;
  std::array<unsigned char, 8> chunk{};
  while (bytes.read(offset, chunk)) {
    const std::uint64_t size = unsigned_of(chunk.data() + 4, 4, big_endian);
    if (rf64 && tag_is(chunk.data(), "ds64")) {
      std::array<unsigned char, 16> sizes{};  // RIFF size, data size
      if (!bytes.read(offset + 8, sizes)) return std::nullopt;
      ds64_data_size = unsigned_of(sizes.data() + 8, 8, false);
    } else if (tag_is(chunk.data(), "data")) {
      const std::uint64_t declared = rf64 && size == 0xFFFFFFFFU ? ds64_data_size : size;
      if (declared == 0xFFFFFFFFU || declared > (1ULL << 62)) return std::nullopt;
      return extent(container, bytes.size(), offset + 8, static_cast<std::int64_t>(declared),
                    bytes_per_frame);
    }
    offset += 8 + static_cast<std::int64_t>(size) + static_cast<std::int64_t>(size & 1U);
  }
  return std::nullopt;
}

// AIFF/AIFC: big-endian chunks, even aligned; COMM declares the frames, SSND holds the data
// after an offset field.
std::optional<DataExtent> aiff(Bytes& bytes, int bytes_per_frame) {
  std::int64_t comm_frames = -1;
  std::int64_t data_start = -1;
  std::int64_t offset = 12;
  std::array<unsigned char, 8> chunk{};
  while ((comm_frames < 0 || data_start < 0) && bytes.read(offset, chunk)) {
    const std::uint64_t size = unsigned_of(chunk.data() + 4, 4, true);
    if (tag_is(chunk.data(), "COMM")) {
      std::array<unsigned char, 6> comm{};  // channels (2), frames (4)
      if (!bytes.read(offset + 8, comm)) return std::nullopt;
      comm_frames = static_cast<std::int64_t>(unsigned_of(comm.data() + 2, 4, true));
    } else if (tag_is(chunk.data(), "SSND")) {
      std::array<unsigned char, 4> data_offset{};
      if (!bytes.read(offset + 8, data_offset)) return std::nullopt;
      data_start =
          offset + 16 + static_cast<std::int64_t>(unsigned_of(data_offset.data(), 4, true));
    }
    offset += 8 + static_cast<std::int64_t>(size) + static_cast<std::int64_t>(size & 1U);
  }
  if (comm_frames <= 0 || data_start < 0) return std::nullopt;
  return extent("AIFF", bytes.size(), data_start, comm_frames * bytes_per_frame, bytes_per_frame);
}

// Sony Wave64: chunks of a 16-byte GUID (its first four bytes spell the old RIFF id) and a
// 64-bit size that counts the 24-byte chunk header, 8-byte aligned.
std::optional<DataExtent> wave64(Bytes& bytes, int bytes_per_frame) {
  std::int64_t offset = 40;  // riff GUID, size, wave GUID
  std::array<unsigned char, 24> chunk{};
  while (bytes.read(offset, chunk)) {
    const std::uint64_t size = unsigned_of(chunk.data() + 16, 8, false);
    if (size < 24 || size > (1ULL << 62)) return std::nullopt;
    if (tag_is(chunk.data(), "data")) {
      return extent("W64", bytes.size(), offset + 24, static_cast<std::int64_t>(size - 24),
                    bytes_per_frame);
    }
    offset += static_cast<std::int64_t>((size + 7) & ~std::uint64_t{7});
  }
  return std::nullopt;
}

// Apple CAF: big-endian chunks of type + signed 64-bit size; the data chunk starts with a
// 4-byte edit count, and a size of -1 means "to the end of the file".
std::optional<DataExtent> caf(Bytes& bytes, int bytes_per_frame) {
  std::int64_t offset = 8;  // "caff", version, flags
  std::array<unsigned char, 12> chunk{};
  while (bytes.read(offset, chunk)) {
    const auto size = static_cast<std::int64_t>(unsigned_of(chunk.data() + 4, 8, true));
    if (tag_is(chunk.data(), "data")) {
      if (size < 4) return std::nullopt;  // -1: no declared length
      return extent("CAF", bytes.size(), offset + 16, size - 4, bytes_per_frame);
    }
    if (size < 0) return std::nullopt;
    offset += 12 + size;
  }
  return std::nullopt;
}

// Sun/NeXT AU: a fixed header with the data offset and size (0xFFFFFFFF: unknown); ".snd" is
// big-endian, "dns." the little-endian variant.
std::optional<DataExtent> au(Bytes& bytes, const std::array<unsigned char, 12>& head,
                             int bytes_per_frame) {
  const bool big_endian = tag_is(head.data(), ".snd");
  const std::uint64_t data_start = unsigned_of(head.data() + 4, 4, big_endian);
  const std::uint64_t size = unsigned_of(head.data() + 8, 4, big_endian);
  if (size == 0xFFFFFFFFU) return std::nullopt;
  return extent("AU", bytes.size(), static_cast<std::int64_t>(data_start),
                static_cast<std::int64_t>(size), bytes_per_frame);
}

}  // namespace

std::optional<DataExtent> data_extent(const std::filesystem::path& file, int bytes_per_frame) {
  if (bytes_per_frame <= 0) return std::nullopt;
  Bytes bytes(file);
  std::array<unsigned char, 12> head{};
  if (!bytes.ok() || !bytes.read(0, head)) return std::nullopt;
  if ((tag_is(head.data(), "RIFF") || tag_is(head.data(), "RIFX") || tag_is(head.data(), "RF64") ||
       tag_is(head.data(), "BW64")) &&
      tag_is(head.data() + 8, "WAVE")) {
    return riff(bytes, head, bytes_per_frame);
  }
  if (tag_is(head.data(), "FORM") &&
      (tag_is(head.data() + 8, "AIFF") || tag_is(head.data() + 8, "AIFC"))) {
    return aiff(bytes, bytes_per_frame);
  }
  if (tag_is(head.data(), "riff")) return wave64(bytes, bytes_per_frame);
  if (tag_is(head.data(), "caff")) return caf(bytes, bytes_per_frame);
  if (tag_is(head.data(), ".snd") || tag_is(head.data(), "dns.")) {
    return au(bytes, head, bytes_per_frame);
  }
  return std::nullopt;
}

}  // namespace dronetrack::capture
