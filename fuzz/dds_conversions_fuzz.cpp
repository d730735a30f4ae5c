// The DDS edge (dds_idl/conversions.cpp): IDL C samples built field by field from the fuzz
// bytes, as any process on the network could publish them (NaN/inf and extreme doubles,
// unterminated key strings, sequence lengths beyond their bound or a null buffer), through our
// validation and conversion to the core types. Properties: from_idl never reads outside the
// sample, and an accepted sample converts back (to_idl) into one that is accepted again with
// the same values, so what a node publishes is what the fusion reads.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "dds_idl/conversions.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

using dronetrack::fuzz::Bytes;
using dronetrack::fuzz::fail;
namespace dds = dronetrack::dds;

// A sequence as the wire gives it: a length, and a buffer holding exactly that many elements
// (none past the sequence's bound plus a few: a deserializer never hands over more), or none.
struct Sequence {
  std::vector<double> storage;
  template <typename S>
  void fill(Bytes& in, S& sequence) {
    const std::uint32_t length = in.take<std::uint8_t>() % 40U;
    const bool null_buffer = in.flag();
    storage.resize(length);
    for (double& value : storage) value = in.number();
    sequence._length = length;
    sequence._maximum = in.flag() ? length : in.take<std::uint32_t>();
    sequence._buffer = null_buffer || length == 0 ? nullptr : storage.data();
    sequence._release = false;
  }
};

void fuzz_doa(Bytes& in, const std::vector<std::string>& ids) {
  dronetrack_Doa sample{};
  in.text(sample.array_id);
  sample.time_ns = in.take<std::int64_t>();
  in.numbers(sample.direction);
  if (in.flag()) {  // mostly a plausible unit direction, so the checks behind it are reached
    const double norm = std::sqrt(sample.direction[0] * sample.direction[0] +
                                  sample.direction[1] * sample.direction[1] +
                                  sample.direction[2] * sample.direction[2]);
    if (norm > 0.0 && std::isfinite(norm))
      for (double& value : sample.direction) value /= norm;
  }
  sample.azimuth_deg = in.number();
  sample.elevation_deg = in.number();
  in.numbers(sample.azel_covariance_rad2);
  sample.quality = in.number();
  sample.snr_db = in.number();
  sample.source_index = in.take<std::int32_t>();
  sample.ambiguity = in.take<std::uint8_t>() % 4U;
  Sequence tdoa;
  Sequence peak_angles;
  Sequence peak_weights;
  tdoa.fill(in, sample.tdoa_s);
  sample.acoustic_valid = in.flag();
  sample.fundamental_hz = in.number();
  sample.comb_strength = in.number();
  sample.harmonic_count = in.take<std::int32_t>();
  sample.broadband_share = in.number();
  sample.comb_persistence = in.number();
  sample.fundamental_spread = in.number();
  sample.level_modulation_db = in.number();
  sample.acoustic_history_s = in.number();
  sample.array_moving = in.flag();
  in.numbers(sample.array_centre_m);
  in.numbers(sample.array_orientation);
  if (in.flag()) {
    sample.array_orientation[0] = 1.0;
    sample.array_orientation[1] = sample.array_orientation[2] = sample.array_orientation[3] = 0.0;
  }
  in.numbers(sample.ambiguity_axis);
  sample.cone_angle_rad = in.number();
  sample.cone_angle_variance_rad2 = in.number();
  peak_angles.fill(in, sample.cone_peak_angle_rad);
  peak_weights.fill(in, sample.cone_peak_weight);

  dronetrack::doa::DoaMeasurement measurement;
  if (dds::from_idl(sample, ids, measurement) != dds::SampleProblem::none) return;
  if (!measurement.direction.allFinite() || measurement.array_index < 0 ||
      measurement.pair_count < 0 || measurement.pair_count > dronetrack::doa::kMaxPairs ||
      measurement.cone_peak_count < 0 ||
      measurement.cone_peak_count > dronetrack::doa::kMaxConePeaks)
    fail("accepted Doa converts to an out-of-range measurement");
  dronetrack_Doa again{};
  dds::to_idl(measurement, 0, again);
  dronetrack::doa::DoaMeasurement back;
  if (dds::from_idl(again, ids, back) != dds::SampleProblem::none)
    fail("a converted Doa is refused when sent again");
  if (back.array_index != measurement.array_index || back.pair_count != measurement.pair_count ||
      back.cone_peak_count != measurement.cone_peak_count)
    fail("a Doa changes on its way back");
}

void fuzz_pose(Bytes& in) {
  dronetrack_ArrayPose sample{};
  in.text(sample.array_id);
  sample.time_ns = in.take<std::int64_t>();
  in.numbers(sample.position_m);
  sample.yaw_deg = in.number();
  sample.pitch_deg = in.number();
  sample.roll_deg = in.number();
  dronetrack::doa::PoseSample pose;
  if (dds::from_idl(sample, "N1", pose) != dds::SampleProblem::none) return;
  dronetrack_ArrayPose again{};
  dds::to_idl("N1", pose, 0, again);
  dronetrack::doa::PoseSample back;
  if (dds::from_idl(again, "N1", back) != dds::SampleProblem::none)
    fail("a converted ArrayPose is refused when sent again");
}

void fuzz_status(Bytes& in, const std::vector<std::string>& ids) {
  dronetrack_NodeStatus sample{};
  in.text(sample.array_id);
  sample.time_ns = in.take<std::int64_t>();
  sample.alive = in.flag();
  sample.sample_rate_hz = in.number();
  sample.overruns = in.take<std::int64_t>();
  sample.dropouts = in.take<std::int64_t>();
  sample.clipped_samples = in.take<std::int64_t>();
  sample.non_finite_samples = in.take<std::int64_t>();
  sample.level_dbfs = in.number();
  sample.noise_floor_dbfs = in.number();
  sample.snr_db = in.number();
  sample.detecting = in.flag();
  in.text(sample.software_version);
  sample.incident_clips = in.take<std::int64_t>();
  sample.incident_write_errors = in.take<std::int64_t>();
  sample.channel_count = in.take<std::uint8_t>();
  for (auto& channel : sample.channels) {
    channel.problems = in.take<std::uint8_t>();
    channel.problems_seen = in.take<std::uint8_t>();
    channel.non_finite_samples = in.take<std::int64_t>();
    channel.clipped_samples = in.take<std::int64_t>();
    channel.rms_dbfs = in.number();
  }
  dronetrack::doa::NodeStatus status;
  if (dds::from_idl(sample, ids, status) != dds::SampleProblem::none) return;
  if (status.channels.size() > dronetrack::doa::kMaxStatusChannels)
    fail("accepted NodeStatus has more channels than the IDL holds");
  dronetrack_NodeStatus again{};
  dds::to_idl(status, sample.time_ns, again);
  dronetrack::doa::NodeStatus back;
  if (dds::from_idl(again, ids, back) != dds::SampleProblem::none)
    fail("a converted NodeStatus is refused when sent again");
}

void fuzz_track(Bytes& in) {
  dronetrack_Track sample{};
  sample.id = in.take<std::int32_t>();
  sample.time_ns = in.take<std::int64_t>();
  in.numbers(sample.position_m);
  in.numbers(sample.velocity_mps);
  in.numbers(sample.acceleration_mps2);
  in.numbers(sample.covariance_upper);
  sample.status = in.take<std::uint8_t>() % 4U;
  sample.contributing_arrays = in.take<std::uint64_t>();
  sample.last_update_ns = in.take<std::int64_t>();
  sample.track_class = in.take<std::uint8_t>() % 5U;
  sample.class_confidence = in.number();
  sample.one_array = in.flag();
  sample.hypotheses = in.take<std::int32_t>();
  dronetrack::fusion::TrackReport report;
  if (dds::from_idl(sample, report) != dds::SampleProblem::none) return;
  if (!report.covariance.allFinite() || report.hypotheses < 1)
    fail("accepted Track converts to an out-of-range report");
}

void fuzz_alert(Bytes& in) {
  dronetrack_Alert sample{};
  in.text(sample.zone);
  sample.track_id = in.take<std::int32_t>();
  sample.entered = in.flag();
  sample.time_ns = in.take<std::int64_t>();
  in.numbers(sample.position_m);
  sample.event = in.take<std::uint8_t>() % 4U;
  sample.track_class = in.take<std::uint8_t>() % 5U;
  sample.previous_class = in.take<std::uint8_t>() % 5U;
  dronetrack::fusion::ZoneEvent event;
  if (dds::from_idl(sample, event) != dds::SampleProblem::none) return;
  dronetrack_Alert again{};
  dds::to_idl(event, again);
  dronetrack::fusion::ZoneEvent back;
  if (dds::from_idl(again, back) != dds::SampleProblem::none)
    fail("a converted Alert is refused when sent again");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::vector<std::string> ids = {"N1", "N2", "N3", "N4"};
  Bytes in(data, size);
  // The first byte picks the topic, so each input is one sample of one type.
  switch (in.take<std::uint8_t>() % 5U) {
    case 0:
      fuzz_doa(in, ids);
      break;
    case 1:
      fuzz_pose(in);
      break;
    case 2:
      fuzz_status(in, ids);
      break;
    case 3:
      fuzz_track(in);
      break;
    default:
      fuzz_alert(in);
      break;
  }
  return 0;
}
