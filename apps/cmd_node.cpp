// `dronetrack node SITE.json --array ID [--device N | --recording F] [--realtime] [--domain N]`:
// one array node as its own process. Audio (a recording or a live device) -> NodePipeline ->
// a Doa sample per direction found, and a NodeStatus sample every second of stream time.
//
// Time on the wire: recordings use recording time (t = 0 at sample 0, SPEC 2), so every node
// replaying the same scene shares one clock without any synchronisation. Live capture uses Unix
// time: the stream's start on the system clock plus the sample count, so all nodes of a site
// share one clock as far as their system clocks agree (docs/deployment.md: chrony/PTP).
//
// A moving array (issue 15): replaying a recording, each DOA is stamped from the array's
// pose_file; live (or with --pose-topic), from the ArrayPose topic on the same clock, each DOA
// waiting until the poses around its time have arrived (apps/live_pose_stamper.hpp).
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <thread>

#include "apps/array_node.hpp"
#include "apps/cli_checks.hpp"
#include "apps/commands.hpp"
#include "apps/dds_options.hpp"
#include "apps/dds_support.hpp"
#include "apps/incident_recorder.hpp"
#include "apps/live_pose_stamper.hpp"
#include "apps/live_state_observer.hpp"
#include "apps/metrics.hpp"
#include "apps/signals.hpp"
#include "capture/portaudio_source.hpp"
#include "capture/recording_time.hpp"
#include "capture/wrapped_source.hpp"
#include "common/log.hpp"
#include "config/site_config.hpp"
#include "dds_idl/conversions.hpp"
#include "dds_idl/dds.hpp"
#include "dds_idl/topics.hpp"
#include "http_api/http_server.hpp"

namespace dronetrack::apps {
namespace {

using Clock = std::chrono::system_clock;

struct NodeArguments {
  std::string site;
  std::string array;
  std::optional<int> device;
  std::string recording;
  bool realtime = false;
  bool loop = false;
  std::optional<double> epoch_unix_s;
  DdsOptions dds;  // an empty identity: the array id
  double sample_rate_hz = 48000.0;
  double block_s = 0.01;
  bool pose_topic = false;
  std::string metrics_listen;  // HOST:PORT of the /metrics listener; "" for none
};

// ThrottledWarnings kinds of the pose stream, and their texts (which must outlive the log).
enum PoseWarning : int { kBadPose = 0, kRefusedPose = 1, kUnposedDoa = 2 };
struct PoseWarningTexts {
  explicit PoseWarningTexts(const std::string& array_id)
      : bad("node " + array_id + ": ArrayPose samples not finite or out of bounds"),
        refused("node " + array_id + ": ArrayPose samples not after the newest (out of order)"),
        unposed("node " + array_id + ": DOAs without an ArrayPose around their time (dropped)") {}
  std::string bad;
  std::string refused;
  std::string unposed;
};

// Skips, without processing, the part of a recording whose due time has long passed: a node
// restarted with the same --epoch resumes where the other nodes are instead of replaying
// minutes of stale audio that the fusion would only count as too late.
class SkippingSource : public capture::WrappedSource {
 public:
  SkippingSource(std::unique_ptr<capture::AudioSource> inner, double skip_to_s)
      : WrappedSource(std::move(inner)), skip_to_s_(skip_to_s) {}
  bool next(doa::AudioBlockView& block) override {
    while (inner().next(block)) {
      const double block_end_s =
          static_cast<double>(block.first_sample + static_cast<std::int64_t>(block.frames)) /
          sample_rate_hz();
      if (block_end_s > skip_to_s_) return true;
    }
    return false;
  }

 private:
  double skip_to_s_;
};

// --loop: the recording again and again, its samples numbered on across the passes, so the
// stream time keeps rising (a soak test's endless input; scripts/soak.sh). The file is opened
// again at each pass: one allocation per pass, none per block.
class LoopingSource : public capture::AudioSource {
 public:
  using Opener = std::function<std::unique_ptr<capture::AudioSource>()>;
  explicit LoopingSource(Opener open) : open_(std::move(open)), inner_(open_()) {}
  bool next(doa::AudioBlockView& block) override {
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (inner_->next(block)) {
        block.first_sample += offset_;
        end_ = block.first_sample + static_cast<std::int64_t>(block.frames);
        return true;
      }
      if (end_ == offset_) return false;  // an empty pass: the file holds no audio
      offset_ = end_;
      inner_ = open_();
    }
    return false;
  }
  double sample_rate_hz() const override { return inner_->sample_rate_hz(); }
  int channels() const override { return inner_->channels(); }
  const capture::SourceCounters& counters() const override { return inner_->counters(); }
  std::string describe() const override { return inner_->describe() + " (looped)"; }

 private:
  Opener open_;
  std::unique_ptr<capture::AudioSource> inner_;
  std::int64_t offset_ = 0;  // first sample number of the current pass
  std::int64_t end_ = 0;     // one past the last sample delivered
};

// Every pose waiting on the reader into the stamper, moved to the node's stream clock (the wire
// carries stream time + offset). Other arrays' poses are not this node's business.
void take_poses(const dds::Reader<dronetrack_ArrayPose>& reader, const std::string& array_id,
                double offset_s, LivePoseStamper& stamper, ThrottledWarnings& warnings,
                const PoseWarningTexts& texts) {
  for (;;) {
    dds::Samples<dronetrack_ArrayPose> samples = reader.take();
    if (samples.empty()) return;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (!samples.info(i).valid_data) continue;
      doa::PoseSample pose;
      const dds::SampleProblem problem = dds::from_idl(samples.data(i), array_id, pose);
      if (problem == dds::SampleProblem::unknown_array) continue;
      if (problem != dds::SampleProblem::none) {
        warnings.count(kBadPose, texts.bad.c_str());
        continue;
      }
      pose.time_s -= offset_s;
      if (!stamper.add_pose(pose)) warnings.count(kRefusedPose, texts.refused.c_str());
    }
  }
}

double unix_now_s() {
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

int run(const NodeArguments& arguments) {
  std::vector<std::string> warnings;
  config::LoadOptions load_options;
  // Only the recording this node reads matters; it is checked when it is opened.
  load_options.check_recordings = false;
  const config::SiteConfig site = config::load_site_config(arguments.site, warnings, load_options);
  for (const auto& warning : warnings) log::warn(warning);
  const int array_index = site.array_index(arguments.array);
  if (array_index < 0) {
    std::string known;
    for (const auto& id : array_ids(site)) known += (known.empty() ? "" : ", ") + id;
    throw UserError("--array " + arguments.array + ": no such array in " + arguments.site +
                    " (arrays: " + known + ")");
  }
  const config::ArrayConfig& array = site.arrays[static_cast<std::size_t>(array_index)];
  // Refused (exit 2) before any audio is opened: beyond loopback without TLS and users.
  std::optional<http_api::HttpOptions> metrics_options;
  if (!arguments.metrics_listen.empty()) {
    metrics_options = http_options_for(site, arguments.metrics_listen, {}, "--metrics-listen");
    metrics_options->web_root.clear();
  }
  const int domain = resolve_domain(site, arguments.dds.domain);
  const std::optional<int> device = arguments.device ? arguments.device : array.device;
  const bool live = arguments.device.has_value() ||
                    (arguments.recording.empty() && array.recording.empty() && device);
  const bool pose_from_topic = array.pose_topic || arguments.pose_topic;
  if (pose_from_topic && !live && !arguments.realtime) {
    throw UserError("array " + arguments.array +
                    " takes its pose from the ArrayPose topic, which runs in real time: replay "
                    "its recording with --realtime");
  }

  // The source. Live: the stream's start time on the system clock gives Unix time.
  capture::PortAudioSource* live_source = nullptr;
  std::unique_ptr<capture::AudioSource> source;
  double epoch_unix_s = 0.0;
  if (live) {
    capture::PortAudioOptions options;
    options.device_index = device.value_or(-1);
    options.mics = static_cast<int>(array.geometry.mic_count());
    options.channel_map = array.channel_map;
    options.sample_rate_hz = arguments.sample_rate_hz;
    options.block_frames = capture::live_block_frames(arguments.sample_rate_hz);
    auto portaudio = std::make_unique<capture::PortAudioSource>(options);
    live_source = portaudio.get();
    source = std::move(portaudio);
  } else {
    const std::filesystem::path recording =
        arguments.recording.empty() ? array.recording : std::filesystem::path(arguments.recording);
    if (recording.empty()) {
      throw UserError("array " + arguments.array +
                      " has no recording in the site config: give --recording F or --device N");
    }
    if (!pose_from_topic) {
      const std::string problem =
          pose_span_problem(site, static_cast<std::size_t>(array_index), recording);
      if (!problem.empty()) throw UserError(problem);
    }
    if (arguments.loop) {
      const double block_s = arguments.block_s;
      source = std::make_unique<LoopingSource>(
          [&array, recording, block_s] { return open_recording(array, recording, block_s); });
    } else {
      source = open_recording(array, recording, arguments.block_s);
    }
    if (arguments.realtime) {
      epoch_unix_s = arguments.epoch_unix_s.value_or(unix_now_s());
      const double overdue_s = unix_now_s() - epoch_unix_s;
      if (overdue_s > 1.0) {
        log::info("node ", arguments.array, ": skipping the first ", overdue_s - 0.5,
                  " s of the recording (already due since --epoch)");
        source = std::make_unique<SkippingSource>(std::move(source), overdue_s - 0.5);
      }
    }
  }
  ArrayNode node(site, array_index, std::move(source), !pose_from_topic);
  // The optional /metrics listener: the operator's server with no page and no API, so the
  // same per-client limits, TLS and users rules hold.
  std::unique_ptr<NodeMetrics> metrics;
  std::unique_ptr<http_api::HttpServer> metrics_server;
  if (!arguments.metrics_listen.empty()) {
    metrics = std::make_unique<NodeMetrics>(node.array_id());
    http_api::HttpOptions options = *metrics_options;
    options.metrics = [&metrics] { return metrics->text(); };
    metrics_server = std::make_unique<http_api::HttpServer>(std::move(options));
    metrics_server->start();
    log::info("node ", node.array_id(), ": metrics on ", metrics_server->url(), "metrics");
  }
  log::info("node ", node.array_id(), ": ", node.source().describe(), ", ", node.sample_rate_hz(),
            " Hz, DDS domain ", domain, live ? ", live" : "",
            arguments.realtime ? ", real time" : "",
            pose_from_topic       ? ", pose from ArrayPose"
            : !array.pose.empty() ? ", pose file"
                                  : "");

  // Participant first: destroyed last. A secure site: this array's identity (or --identity),
  // writing in its own partition, the only one its permissions grant.
  const auto security = security_files(
      site, arguments.dds.identity.empty() ? node.array_id() : arguments.dds.identity);
  dds::Participant participant(domain, security ? &*security : nullptr);
  dds::Topic<dronetrack_Doa> doa_topic(participant);
  dds::Topic<dronetrack_NodeStatus> status_topic(participant);
  dds::Qos doa_qos, status_qos;
  dds::doa_writer_qos(doa_qos);
  dds::status_writer_qos(status_qos);
  if (site.dds.secure()) {
    doa_qos.partitions({dds::array_partition(node.array_id())});
    status_qos.partitions({dds::array_partition(node.array_id())});
  }
  dds::Writer<dronetrack_Doa> doa_writer(participant, doa_topic, doa_qos);
  dds::Writer<dronetrack_NodeStatus> status_writer(participant, status_topic, status_qos);
  std::unique_ptr<dds::Topic<dronetrack_ArrayPose>> pose_topic;
  std::unique_ptr<dds::Reader<dronetrack_ArrayPose>> pose_reader;
  if (pose_from_topic) {
    pose_topic = std::make_unique<dds::Topic<dronetrack_ArrayPose>>(participant);
    dds::Qos pose_qos;
    dds::pose_reader_qos(pose_qos);
    if (site.dds.secure()) pose_qos.partitions({dds::array_partition(node.array_id())});
    pose_reader =
        std::make_unique<dds::Reader<dronetrack_ArrayPose>>(participant, *pose_topic, pose_qos);
  }
  // Incident capture (issue 19): the node's audio goes through the ring; every zone alert the
  // fusion publishes cuts a clip of it, with this node's DOAs of the window.
  std::unique_ptr<IncidentRecorder> incidents;
  std::unique_ptr<dds::Topic<dronetrack_Alert>> alert_topic;
  std::unique_ptr<dds::Reader<dronetrack_Alert>> alert_reader;
  if (site.incident.enabled()) {
    IncidentClock clock{dds::seconds_to_ns(arguments.realtime ? epoch_unix_s : unix_now_s()),
                        "replay", false};
    if (live_source) {
      clock.utc_start_unix_ns = dds::seconds_to_ns(live_source->stream_start_unix_s());
      clock.clock = "system";
    } else if (const auto recorded = capture::read_recording_time(
                   arguments.recording.empty() ? array.recording
                                               : std::filesystem::path(arguments.recording))) {
      clock.utc_start_unix_ns = recorded->utc_start_unix_ns;
      clock.clock = recorded->clock;
    }
    incidents = std::make_unique<IncidentRecorder>(
        site,
        std::vector<IncidentArray>{
            {array_index, node.sample_rate_hz(), static_cast<int>(array.geometry.mic_count())}},
        clock);
    node.set_audio_tap(incidents.get());
    alert_topic = std::make_unique<dds::Topic<dronetrack_Alert>>(participant);
    dds::Qos alert_qos;
    dds::alert_reader_qos(alert_qos);
    alert_reader =
        std::make_unique<dds::Reader<dronetrack_Alert>>(participant, *alert_topic, alert_qos);
  }
  fusion::ZoneEvent alert;
  double next_alert_poll_s = 0.0;
  // Alerts carry wire time: moved to this node's stream time before a clip is asked for.
  auto take_alerts = [&](std::int64_t offset_ns) {
    dds::Samples<dronetrack_Alert> samples = alert_reader->take();
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (!samples.info(i).valid_data ||
          dds::from_idl(samples.data(i), alert) != dds::SampleProblem::none)
        continue;
      alert.time_s -= dds::ns_to_seconds(offset_ns);
      incidents->on_zone_event(alert);
    }
  };
  LivePoseStamper pose_stamper(array.geometry, array.pose_max_gap_s);
  const PoseWarningTexts pose_texts(node.array_id());
  ThrottledWarnings pose_warnings;

  // A volatile sample written before a reader has matched is lost to it. Give discovery a
  // moment (milliseconds on a LAN) before the first block; never wait for a fusion forever.
  const auto discovery_started = std::chrono::steady_clock::now();
  if (doa_writer.wait_for_readers(1, std::chrono::seconds(2))) {
    log::info(
        "node ", node.array_id(), ": fusion matched after ",
        std::chrono::duration<double>(std::chrono::steady_clock::now() - discovery_started).count(),
        " s");
  } else {
    log::warn("node ", node.array_id(), ": no Doa subscriber yet; publishing anyway");
  }
  install_stop_handlers();
  std::vector<doa::DoaMeasurement> doas;
  // A moving node may release a whole queue of DOAs at once.
  doas.reserve(pose_reader ? LivePoseStamper::kMaxPending : 64);
  doa::NodeStatus status;
  dronetrack_Doa doa_sample{};
  dronetrack_NodeStatus status_sample{};
  std::int64_t published = 0;
  std::int64_t write_failures = 0;
  // Recordings: stream time is the wire time. Live: offset by the stream's Unix start.
  auto time_offset_ns = [&]() -> std::int64_t {
    return live_source ? dds::seconds_to_ns(live_source->stream_start_unix_s()) : 0;
  };
  const auto wall_epoch = Clock::time_point(
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(epoch_unix_s)));

  // Pose-topic node: this step's DOAs wait for their poses; those whose pose came are published.
  auto stamp_from_topic = [&](double now_s, std::int64_t offset_ns) {
    take_poses(*pose_reader, node.array_id(), dds::ns_to_seconds(offset_ns), pose_stamper,
               pose_warnings, pose_texts);
    const std::int64_t dropped_before = pose_stamper.dropped();
    pose_stamper.add_doas(doas);
    pose_stamper.release(now_s, doas);
    for (std::int64_t d = dropped_before; d < pose_stamper.dropped(); ++d)
      pose_warnings.count(kUnposedDoa, pose_texts.unposed.c_str());
  };
  auto publish_doas = [&](std::int64_t offset_ns) {
    for (const auto& measurement : doas) {
      dds::to_idl(measurement, offset_ns, doa_sample);
      if (doa_writer.try_write(doa_sample) < 0) {
        ++write_failures;
      } else {
        ++published;
      }
    }
    doas.clear();
  };

  while (!stop_requested()) {
    if (!node.step(doas)) break;
    if (arguments.realtime && !live) {
      // The block is due when its last sample would have been captured.
      std::this_thread::sleep_until(wall_epoch + std::chrono::duration_cast<Clock::duration>(
                                                     std::chrono::duration<double>(node.time_s())));
    }
    const std::int64_t offset_ns = time_offset_ns();
    if (pose_reader) stamp_from_topic(node.time_s(), offset_ns);
    if (incidents) {
      for (const auto& measurement : doas) incidents->on_doa(measurement);
      if (node.time_s() >= next_alert_poll_s) {  // ten times a second is soon enough
        next_alert_poll_s = node.time_s() + 0.1;
        take_alerts(offset_ns);
      }
      incidents->service(false);
    }
    publish_doas(offset_ns);
    if (metrics) {
      metrics->update(published, write_failures, node.diagnostics(),
                      node.source().counters().overruns);
    }
    if (node.status_due(status)) {
      if (incidents) incidents->fill_status(status);
      dds::to_idl(status, offset_ns + dds::seconds_to_ns(status.time_s), status_sample);
      if (status_writer.try_write(status_sample) < 0) ++write_failures;
    }
  }
  if (pose_reader) {
    // The stream ended: the last DOAs' poses may still be on their way (as long as a DOA may
    // wait for them); then whatever is left has no pose and is counted.
    const auto give_up =
        std::chrono::steady_clock::now() +
        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(array.pose_max_gap_s + LivePoseStamper::kWaitMargin_s));
    while (pose_stamper.pending() > 0 && !stop_requested() &&
           std::chrono::steady_clock::now() < give_up) {
      pose_reader->wait(std::chrono::milliseconds(50));
      stamp_from_topic(node.time_s(), time_offset_ns());
      publish_doas(time_offset_ns());
    }
    stamp_from_topic(std::numeric_limits<double>::infinity(), time_offset_ns());
    publish_doas(time_offset_ns());
  }
  if (live_source) live_source->request_stop();
  pose_warnings.flush();
  if (incidents) {
    take_alerts(time_offset_ns());
    incidents->service(true);
  }

  // Say goodbye: readers see alive = false, then the writers' deletion leaves the instances
  // without writers, exactly as a lost liveliness would.
  status = node.status();
  if (incidents) incidents->fill_status(status);
  status.alive = false;
  dds::to_idl(status, time_offset_ns() + dds::seconds_to_ns(status.time_s), status_sample);
  status_writer.try_write(status_sample);
  status_writer.wait_for_acks(std::chrono::milliseconds(500));
  doa_writer.wait_for_acks(std::chrono::milliseconds(500));
  if (metrics) {
    metrics->update(published, write_failures, node.diagnostics(),
                    node.source().counters().overruns);
  }
  if (metrics_server) metrics_server->stop();
  log::info("node ", node.array_id(), ": ", node.time_s(), " s of audio, ", published,
            " DOAs published", write_failures ? ", " : "",
            write_failures ? std::to_string(write_failures) + " writes failed" : "",
            pose_reader
                ? ", " + std::to_string(pose_stamper.dropped()) + " dropped without a pose (" +
                      std::to_string(pose_stamper.refused_poses()) + " poses refused)"
                : "");
  if (stop_requested()) return interrupted_exit_code();
  if (node.source().cut_short()) {
    log::error("node ", node.array_id(), ": ", node.source().describe(),
               " ended before its header's end (truncated while being read)");
    return 1;
  }
  return 0;
}

}  // namespace

void register_node(CLI::App& root, CommandTable& table) {
  auto arguments = std::make_shared<NodeArguments>();
  auto* command = root.add_subcommand(
      "node", "Run one array node: audio in, DOAs and node status out over DDS");
  command->add_option("site", arguments->site, "Site config (JSON, SPEC 3.1)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--array", arguments->array, "Id of this node's array in the site config")
      ->required();
  auto* device =
      command->add_option("--device", arguments->device,
                          "Capture live from this PortAudio device (dronetrack devices)");
  auto* recording =
      command->add_option("--recording", arguments->recording,
                          "Replay this recording instead of the array's configured one");
  device->excludes(recording);
  recording->check(CLI::ExistingFile);
  command->add_flag("--loop", arguments->loop,
                    "Play the recording again and again, time running on (soak tests)");
  command->add_flag("--realtime", arguments->realtime,
                    "Pace a recording at real time (live capture is always real time)");
  command
      ->add_option("--epoch", arguments->epoch_unix_s,
                   "With --realtime: Unix time (s) at which recording time 0 is due; nodes given "
                   "the same epoch replay in step, and a restarted node resumes in step")
      ->needs("--realtime");
  command->add_flag("--pose-topic", arguments->pose_topic,
                    "Take the array's pose from the ArrayPose DDS topic (as the array's "
                    "\"pose_topic\": true does), not from its pose_file");
  add_dds_options(*command, arguments->dds, "the array id");
  command
      ->add_option("--metrics-listen", arguments->metrics_listen,
                   "Serve Prometheus metrics on HOST:PORT (GET /metrics; docs/http_api.md "
                   "\"Metrics\")")
      ->check(http_address());
  command->add_option("--sample-rate", arguments->sample_rate_hz, "Live capture sample rate, Hz")
      ->capture_default_str()
      ->check(CLI::Range(8000.0, 384000.0));
  table.add(command, [arguments]() { return run(*arguments); });
}

}  // namespace dronetrack::apps
