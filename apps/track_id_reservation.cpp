#include "apps/track_id_reservation.hpp"

#include <charconv>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <system_error>

#include "apps/commands.hpp"
#include "common/log.hpp"
#include "common/output_file.hpp"

namespace dronetrack::apps {

namespace {

constexpr std::int64_t kMaxWireId = std::numeric_limits<std::int32_t>::max();
// Far beyond any site's lifetime (a track a second for 290 000 years): a larger number is not
// a high-water mark, it is a corrupted file.
constexpr std::int64_t kMaxStoredId = std::int64_t{1} << 53;

std::int64_t read_next_id(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) {
    std::error_code error;
    if (!std::filesystem::exists(file, error)) return 1;  // the site's first fusion
    throw UserError("--track-ids " + file.string() + ": cannot be read");
  }
  std::stringstream text;
  text << in.rdbuf();
  std::string content = text.str();
  while (!content.empty() && (content.back() == '\n' || content.back() == ' ')) content.pop_back();
  std::int64_t next = 0;
  const auto [end, error] = std::from_chars(content.data(), content.data() + content.size(), next);
  if (error != std::errc() || end != content.data() + content.size() || next < 1 ||
      next > kMaxStoredId) {
    throw UserError("--track-ids " + file.string() +
                    ": expected one track id (the next free one), found \"" +
                    content.substr(0, 32) + "\"");
  }
  return next;
}

}  // namespace

TrackIdReservation::TrackIdReservation(std::filesystem::path file) : file_(std::move(file)) {
  if (file_.empty()) return;
  const std::int64_t next = read_next_id(file_);
  base_ = next - 1;
  reserve(next + kBlock);
  log::info("fusion: track ids from ", wire_id(1), " (", file_.string(), ")");
}

int TrackIdReservation::wire_id(int engine_id) {
  const std::int64_t id = base_ + engine_id;
  if (!file_.empty() && id >= reserved_ && id > failed_at_) {
    reserve(id + kBlock);
    if (id >= reserved_) failed_at_ = id;  // retried at the next new id, not every tick
  }
  // Past INT32_MAX (the IDL's long) ids wrap to 1: reused only after 2^31 tracks.
  return static_cast<int>((id - 1) % kMaxWireId + 1);
}

void TrackIdReservation::reserve(std::int64_t until) {
  try {
    OutputFile out(file_);
    out.write(std::to_string(until));
    out.commit();
    reserved_ = until;
  } catch (const OutputError& error) {
    if (reserved_ == 0) throw;  // at start: the operator must fix the state directory
    log::error("fusion: cannot extend the track id reservation: ", error.what());
  }
}

}  // namespace dronetrack::apps
