// `dronetrack pose-publish --array ID --pose-file F [--epoch E] [--unix-time] [--domain N]`:
// publishes a pose file on the ArrayPose topic in real time, as a GPS/INS adapter on a moving
// array would (issue 15). Line t is published when it is due, at epoch + t on the system clock,
// stamped t (the recording's clock: what `node --realtime --epoch E --pose-topic` replaying the
// same recording uses) or, with --unix-time, epoch + t (the clock of a live node).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <thread>

#include "apps/commands.hpp"
#include "apps/signals.hpp"
#include "common/log.hpp"
#include "config/pose_file.hpp"
#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"

namespace dronetrack::apps {
namespace {

using Clock = std::chrono::system_clock;

struct PosePublishArguments {
  std::string array;
  std::string pose_file;
  std::optional<double> epoch_unix_s;
  bool unix_time = false;
  int domain = 0;
  double max_gap_s = 1.0;
};

double unix_now_s() {
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

int run(const PosePublishArguments& arguments) {
  if (arguments.array.empty() || arguments.array.size() > 63)
    throw UserError("--array: an array id of 1 to 63 characters, got \"" + arguments.array + "\"");
  config::PoseFileLimits limits;
  limits.max_gap_s = arguments.max_gap_s;
  limits.max_gap_key = "--max-gap";
  doa::PoseTrack track;
  try {
    track = config::read_pose_file(arguments.pose_file, limits);
  } catch (const std::runtime_error& failure) {
    throw UserError(failure.what());
  }
  const double epoch_unix_s = arguments.epoch_unix_s.value_or(unix_now_s());
  const std::int64_t offset_ns = arguments.unix_time ? dds::seconds_to_ns(epoch_unix_s) : 0;
  if (!arguments.unix_time && track.start_s() < 0.0)
    throw UserError(arguments.pose_file + ": t starts at " + std::to_string(track.start_s()) +
                    " s; the ArrayPose topic carries times >= 0 (use --unix-time)");

  dds::Participant participant(arguments.domain);
  dds::Topic<dronetrack_ArrayPose> topic(participant);
  dds::Qos qos;
  dds::pose_writer_qos(qos);
  dds::Writer<dronetrack_ArrayPose> writer(participant, topic, qos);
  // A volatile sample written before its node has matched is lost to it: give discovery a
  // moment, never wait forever.
  if (!writer.wait_for_readers(1, std::chrono::seconds(2)))
    log::warn("pose-publish ", arguments.array, ": no ArrayPose subscriber yet; publishing anyway");
  install_stop_handlers();
  log::info("pose-publish ", arguments.array, ": ", track.samples().size(), " poses, t ",
            track.start_s(), " to ", track.end_s(), " s, DDS domain ", arguments.domain);

  dronetrack_ArrayPose sample{};
  std::int64_t published = 0;
  std::int64_t write_failures = 0;
  for (const doa::PoseSample& pose : track.samples()) {
    const double due_unix_s = epoch_unix_s + pose.time_s;
    // Short sleeps, so a stop request is heard within 0.1 s.
    while (!stop_requested()) {
      const double wait_s = due_unix_s - unix_now_s();
      if (wait_s <= 0.0) break;
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(wait_s, 0.1)));
    }
    if (stop_requested()) break;
    dds::to_idl(arguments.array, pose, offset_ns, sample);
    if (writer.try_write(sample) < 0)
      ++write_failures;
    else
      ++published;
  }
  writer.wait_for_acks(std::chrono::milliseconds(500));
  log::info("pose-publish ", arguments.array, ": ", published, " poses published",
            write_failures ? ", " + std::to_string(write_failures) + " writes failed" : "");
  if (stop_requested()) return interrupted_exit_code();
  return write_failures == 0 ? 0 : 1;
}

}  // namespace

void register_pose_publish(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<PosePublishArguments>();
  auto* command = root.add_subcommand(
      "pose-publish",
      "Publish a moving array's pose file on the ArrayPose DDS topic in real time (what a "
      "GPS/INS adapter does)");
  command->add_option("--array", arguments->array, "Id of the array that moves")->required();
  command
      ->add_option(
          "--pose-file", arguments->pose_file,
          "JSON lines {\"t\": s, \"position_m\": [x, y, z], \"yaw_deg\": d} (docs/contract.md)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option(
      "--epoch", arguments->epoch_unix_s,
      "Unix time (s) at which t = 0 is due (default: now); give the node's --epoch");
  command->add_flag("--unix-time", arguments->unix_time,
                    "Stamp poses epoch + t (a live node's clock), not t (a recording's clock)");
  command
      ->add_option("--max-gap", arguments->max_gap_s,
                   "Largest gap between pose lines, s (as the array's pose_max_gap_s)")
      ->capture_default_str()
      ->check(CLI::Range(1e-3, 60.0));
  command->add_option("--domain", arguments->domain, "DDS domain id")
      ->capture_default_str()
      ->check(CLI::Range(0, 232));
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
