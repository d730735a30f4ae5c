#include "dds_idl/conversions.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

namespace dronetrack::dds {

namespace {

constexpr std::size_t kArrayIdBound = sizeof(dronetrack_Doa{}.array_id);

// A direction further than this from unit length is not a direction (the node normalises).
constexpr double kUnitTolerance = 1e-3;
// An array or pose beyond this from the site origin is a unit or sign mistake (as the site config).
constexpr double kMaxPositionAbs_m = 1e5;

// Latest sample time taken (about the year 2096 in Unix time): beyond ~9.2e18 ns the seconds a
// sample converts to no longer convert back into an int64 (llround overflows), so what a node
// forwards would turn negative. Found by fuzz/dds_conversions' round-trip property.
constexpr std::int64_t kMaxTime_ns = 4'000'000'000'000'000'000;
bool absurd(std::int64_t time_ns) { return time_ns < 0 || time_ns > kMaxTime_ns; }

bool finite(double value) { return std::isfinite(value); }
template <std::size_t N>
bool all_finite(const double (&values)[N]) {
  return std::all_of(std::begin(values), std::end(values), finite);
}

// The key string of a sample from the wire: bounded by its array, so an unterminated one cannot
// run past it.
template <std::size_t N>
std::string_view bounded_view(const char (&field)[N]) {
  return {field, strnlen(field, N)};
}

int index_of(std::string_view id, const std::vector<std::string>& array_ids) {
  for (std::size_t i = 0; i < array_ids.size(); ++i) {
    if (array_ids[i] == id) return static_cast<int>(i);
  }
  return -1;
}

Eigen::Vector3d vector3(const double (&values)[3]) { return {values[0], values[1], values[2]}; }
void put_vector3(const Eigen::Vector3d& vector, double (&values)[3]) {
  for (int i = 0; i < 3; ++i) values[i] = vector[i];
}

// The pose stamp, cone and mirror fields of a Doa sample: finite, a unit quaternion, a unit axis
// where the ambiguity needs one, a cone angle in [0, pi] with a positive variance, matched peak
// sequences within their bound.
SampleProblem check_doa_geometry(const dronetrack_Doa& sample) {
  if (!all_finite(sample.array_centre_m) || !all_finite(sample.array_orientation) ||
      !all_finite(sample.ambiguity_axis) || !finite(sample.cone_angle_rad) ||
      !finite(sample.cone_angle_variance_rad2)) {
    return SampleProblem::non_finite;
  }
  const auto& angles = sample.cone_peak_angle_rad;
  const auto& weights = sample.cone_peak_weight;
  if (angles._length > static_cast<std::uint32_t>(doa::kMaxConePeaks) ||
      weights._length != angles._length || (angles._length > 0 && angles._buffer == nullptr) ||
      (weights._length > 0 && weights._buffer == nullptr)) {
    return SampleProblem::oversized_sequence;
  }
  for (std::uint32_t k = 0; k < angles._length; ++k) {
    if (!finite(angles._buffer[k]) || !finite(weights._buffer[k])) return SampleProblem::non_finite;
    if (angles._buffer[k] < 0.0 || angles._buffer[k] > std::numbers::pi || weights._buffer[k] < 0.0)
      return SampleProblem::bad_value;
  }
  const double quaternion_norm =
      std::sqrt(sample.array_orientation[0] * sample.array_orientation[0] +
                sample.array_orientation[1] * sample.array_orientation[1] +
                sample.array_orientation[2] * sample.array_orientation[2] +
                sample.array_orientation[3] * sample.array_orientation[3]);
  if (std::abs(quaternion_norm - 1.0) > kUnitTolerance ||
      vector3(sample.array_centre_m).cwiseAbs().maxCoeff() > kMaxPositionAbs_m) {
    return SampleProblem::bad_value;
  }
  const bool needs_axis = sample.ambiguity != 0;
  if (needs_axis && std::abs(vector3(sample.ambiguity_axis).norm() - 1.0) > kUnitTolerance)
    return SampleProblem::bad_value;
  const bool cone = sample.ambiguity == static_cast<std::uint8_t>(doa::DoaAmbiguity::cone);
  if (cone && (sample.cone_angle_rad < 0.0 || sample.cone_angle_rad > std::numbers::pi ||
               !(sample.cone_angle_variance_rad2 > 0.0))) {
    return SampleProblem::bad_value;
  }
  if (!cone && angles._length > 0) return SampleProblem::bad_value;
  return SampleProblem::none;
}

}  // namespace

std::int64_t seconds_to_ns(double time_s) { return std::llround(time_s * 1e9); }
double ns_to_seconds(std::int64_t time_ns) {
  // Split so Unix-time nanoseconds keep their sub-microsecond part.
  const std::int64_t whole_s = time_ns / 1'000'000'000;
  const std::int64_t rest_ns = time_ns % 1'000'000'000;
  return static_cast<double>(whole_s) + static_cast<double>(rest_ns) * 1e-9;
}

const char* to_string(SampleProblem problem) {
  switch (problem) {
    case SampleProblem::none:
      return "none";
    case SampleProblem::empty_key:
      return "empty_key";
    case SampleProblem::unknown_array:
      return "unknown_array";
    case SampleProblem::non_finite:
      return "non_finite";
    case SampleProblem::absurd_time:
      return "absurd_time";
    case SampleProblem::oversized_sequence:
      return "oversized_sequence";
    case SampleProblem::bad_value:
      return "bad_value";
    case SampleProblem::foreign_partition:
      return "foreign_partition";
  }
  return "unknown";
}

// ---- Doa ----

void to_idl(const doa::DoaMeasurement& measurement, std::int64_t time_offset_ns,
            dronetrack_Doa& sample) {
  copy_bounded(sample.array_id, measurement.array_id);
  sample.time_ns = time_offset_ns + seconds_to_ns(measurement.time_s);
  put_vector3(measurement.direction, sample.direction);
  sample.azimuth_deg = doa::azimuth_deg(measurement.direction);
  sample.elevation_deg = doa::elevation_deg(measurement.direction);
  sample.azel_covariance_rad2[0] = measurement.azel_covariance_rad2(0, 0);
  sample.azel_covariance_rad2[1] = measurement.azel_covariance_rad2(0, 1);
  sample.azel_covariance_rad2[2] = measurement.azel_covariance_rad2(1, 1);
  sample.quality = measurement.quality;
  sample.snr_db = measurement.snr_db;
  sample.source_index = measurement.source_index;
  const doa::AcousticFeatures& acoustic = measurement.acoustic;
  sample.acoustic_valid = acoustic.valid;
  sample.fundamental_hz = acoustic.fundamental_hz;
  sample.comb_strength = acoustic.comb_strength;
  sample.harmonic_count = acoustic.harmonic_count;
  sample.broadband_share = acoustic.broadband_share;
  sample.comb_persistence = acoustic.comb_persistence;
  sample.fundamental_spread = acoustic.fundamental_spread;
  sample.level_modulation_db = acoustic.level_modulation_db;
  sample.acoustic_history_s = acoustic.history_s;
  sample.ambiguity = static_cast<std::uint8_t>(measurement.ambiguity);
  const auto pairs =
      static_cast<std::uint32_t>(std::clamp(measurement.pair_count, 0, doa::kMaxPairs));
  sample.tdoa_s._maximum = pairs;
  sample.tdoa_s._length = pairs;
  // dds_write only reads through this pointer; the cast drops const for the C struct's sake.
  sample.tdoa_s._buffer = const_cast<double*>(measurement.tdoa_s.data());
  sample.tdoa_s._release = false;
  sample.array_moving = measurement.pose.moving;
  put_vector3(measurement.pose.centre_m, sample.array_centre_m);
  const Eigen::Quaterniond& q = measurement.pose.array_to_site;
  sample.array_orientation[0] = q.w();
  sample.array_orientation[1] = q.x();
  sample.array_orientation[2] = q.y();
  sample.array_orientation[3] = q.z();
  put_vector3(measurement.ambiguity_axis, sample.ambiguity_axis);
  sample.cone_angle_rad = measurement.cone_angle_rad;
  sample.cone_angle_variance_rad2 = measurement.cone_angle_variance_rad2;
  const auto peaks =
      static_cast<std::uint32_t>(std::clamp(measurement.cone_peak_count, 0, doa::kMaxConePeaks));
  for (auto* sequence : {&sample.cone_peak_angle_rad, &sample.cone_peak_weight}) {
    sequence->_maximum = peaks;
    sequence->_length = peaks;
    sequence->_release = false;
  }
  sample.cone_peak_angle_rad._buffer = const_cast<double*>(measurement.cone_peak_angle_rad.data());
  sample.cone_peak_weight._buffer = const_cast<double*>(measurement.cone_peak_weight.data());
}

SampleProblem from_idl(const dronetrack_Doa& sample, const std::vector<std::string>& array_ids,
                       doa::DoaMeasurement& out) {
  const std::string_view id = bounded_view(sample.array_id);
  if (id.empty()) return SampleProblem::empty_key;
  const int index = index_of(id, array_ids);
  if (index < 0) return SampleProblem::unknown_array;
  if (!all_finite(sample.direction) || !finite(sample.azimuth_deg) ||
      !finite(sample.elevation_deg) || !all_finite(sample.azel_covariance_rad2) ||
      !finite(sample.quality) || !finite(sample.snr_db)) {
    return SampleProblem::non_finite;
  }
  if (absurd(sample.time_ns)) return SampleProblem::absurd_time;
  if (sample.tdoa_s._length > static_cast<std::uint32_t>(doa::kMaxPairs) ||
      (sample.tdoa_s._length > 0 && sample.tdoa_s._buffer == nullptr)) {
    return SampleProblem::oversized_sequence;
  }
  for (std::uint32_t i = 0; i < sample.tdoa_s._length; ++i) {
    if (!finite(sample.tdoa_s._buffer[i])) return SampleProblem::non_finite;
  }
  if (const SampleProblem problem = check_doa_geometry(sample); problem != SampleProblem::none)
    return problem;
  const Eigen::Vector3d direction = vector3(sample.direction);
  const double var_az = sample.azel_covariance_rad2[0];
  const double cov_azel = sample.azel_covariance_rad2[1];
  const double var_el = sample.azel_covariance_rad2[2];
  if (std::abs(direction.norm() - 1.0) > kUnitTolerance || var_az <= 0.0 || var_el <= 0.0 ||
      cov_azel * cov_azel >= var_az * var_el || sample.source_index < 0 || sample.ambiguity > 2) {
    return SampleProblem::bad_value;
  }
  out.array_id.assign(id);  // within the id's capacity after the first sample: no allocation
  out.array_index = index;
  out.time_s = ns_to_seconds(sample.time_ns);
  out.direction = direction.normalized();
  out.azel_covariance_rad2 << var_az, cov_azel, cov_azel, var_el;
  out.quality = sample.quality;
  out.snr_db = sample.snr_db;
  out.source_index = sample.source_index;
  out.ambiguity = static_cast<doa::DoaAmbiguity>(sample.ambiguity);
  out.pair_count = static_cast<int>(sample.tdoa_s._length);
  out.tdoa_s.fill(0.0);
  std::copy_n(sample.tdoa_s._buffer, sample.tdoa_s._length, out.tdoa_s.begin());
  out.pose.moving = sample.array_moving;
  out.pose.centre_m = vector3(sample.array_centre_m);
  out.pose.array_to_site =
      Eigen::Quaterniond(sample.array_orientation[0], sample.array_orientation[1],
                         sample.array_orientation[2], sample.array_orientation[3])
          .normalized();
  out.ambiguity_axis = vector3(sample.ambiguity_axis);
  if (out.ambiguity != doa::DoaAmbiguity::none) out.ambiguity_axis.normalize();
  out.cone_angle_rad = sample.cone_angle_rad;
  out.cone_angle_variance_rad2 = sample.cone_angle_variance_rad2;
  out.cone_peak_count = static_cast<int>(sample.cone_peak_angle_rad._length);
  std::copy_n(sample.cone_peak_angle_rad._buffer, out.cone_peak_count,
              out.cone_peak_angle_rad.begin());
  std::copy_n(sample.cone_peak_weight._buffer, out.cone_peak_count, out.cone_peak_weight.begin());
  out.acoustic = doa::AcousticFeatures{};
  if (sample.acoustic_valid) {
    const double values[] = {sample.fundamental_hz,     sample.comb_strength,
                             sample.broadband_share,    sample.comb_persistence,
                             sample.fundamental_spread, sample.level_modulation_db,
                             sample.acoustic_history_s};
    // A malformed feature block costs the DOA its acoustic vote, not the DOA.
    const bool sane = std::all_of(std::begin(values), std::end(values),
                                  [](double v) { return std::isfinite(v) && v >= 0.0; }) &&
                      sample.comb_strength <= 1.0 && sample.broadband_share <= 1.0 &&
                      sample.comb_persistence <= 1.0 && sample.harmonic_count >= 0;
    if (sane) {
      out.acoustic = {true,
                      sample.fundamental_hz,
                      sample.comb_strength,
                      static_cast<int>(sample.harmonic_count),
                      sample.broadband_share,
                      sample.comb_persistence,
                      sample.fundamental_spread,
                      sample.level_modulation_db,
                      sample.acoustic_history_s};
    }
  }
  return SampleProblem::none;
}

// ---- ArrayPose ----

void to_idl(std::string_view array_id, const doa::PoseSample& pose, std::int64_t time_offset_ns,
            dronetrack_ArrayPose& sample) {
  copy_bounded(sample.array_id, array_id);
  sample.time_ns = time_offset_ns + seconds_to_ns(pose.time_s);
  put_vector3(pose.position_m, sample.position_m);
  sample.yaw_deg = pose.yaw_deg;
  sample.pitch_deg = pose.pitch_deg;
  sample.roll_deg = pose.roll_deg;
}

SampleProblem from_idl(const dronetrack_ArrayPose& sample, std::string_view array_id,
                       doa::PoseSample& out) {
  const std::string_view id = bounded_view(sample.array_id);
  if (id.empty()) return SampleProblem::empty_key;
  if (id != array_id) return SampleProblem::unknown_array;
  if (!all_finite(sample.position_m) || !finite(sample.yaw_deg) || !finite(sample.pitch_deg) ||
      !finite(sample.roll_deg)) {
    return SampleProblem::non_finite;
  }
  if (absurd(sample.time_ns)) return SampleProblem::absurd_time;
  const Eigen::Vector3d position = vector3(sample.position_m);
  if (position.cwiseAbs().maxCoeff() > kMaxPositionAbs_m || std::abs(sample.yaw_deg) > 360.0 ||
      std::abs(sample.pitch_deg) > 90.0 || std::abs(sample.roll_deg) > 360.0) {
    return SampleProblem::bad_value;
  }
  out = {ns_to_seconds(sample.time_ns), position, sample.yaw_deg, sample.pitch_deg,
         sample.roll_deg};
  return SampleProblem::none;
}

// ---- NodeStatus ----

void to_idl(const doa::NodeStatus& status, std::int64_t time_ns, dronetrack_NodeStatus& sample) {
  copy_bounded(sample.array_id, status.array_id);
  sample.time_ns = time_ns;
  sample.alive = status.alive;
  sample.sample_rate_hz = status.sample_rate_hz;
  sample.overruns = status.overruns;
  sample.dropouts = status.dropouts;
  sample.clipped_samples = status.clipped_samples;
  sample.non_finite_samples = status.non_finite_samples;
  sample.level_dbfs = status.level_dbfs;
  sample.noise_floor_dbfs = status.noise_floor_dbfs;
  sample.snr_db = status.snr_db;
  sample.detecting = status.detecting;
  sample.closure_residual_us = status.closure_residual_us;
  sample.fit_residual_us = status.fit_residual_us;
  copy_bounded(sample.software_version, status.software_version);
  sample.incident_clips = status.incident_clips;
  sample.incident_write_errors = status.incident_write_errors;
  const std::size_t channels = std::min(status.channels.size(), doa::kMaxStatusChannels);
  sample.channel_count = static_cast<std::uint8_t>(channels);
  for (std::size_t c = 0; c < doa::kMaxStatusChannels; ++c) {
    dronetrack_ChannelHealth& out = sample.channels[c];
    if (c >= channels) {
      out = dronetrack_ChannelHealth{};
      continue;
    }
    const doa::ChannelStatus& channel = status.channels[c];
    out.problems = channel.problems;
    out.problems_seen = channel.problems_seen;
    out.non_finite_samples = channel.non_finite_samples;
    out.clipped_samples = channel.clipped_samples;
    out.rms_dbfs = channel.rms_dbfs;
    out.array_problems = channel.array_problems;
    out.array_problems_seen = channel.array_problems_seen;
    out.level_offset_db = channel.level_offset_db;
    out.delay_offset_us = channel.delay_offset_us;
    out.delay_std_us = channel.delay_std_us;
  }
}

SampleProblem from_idl(const dronetrack_NodeStatus& sample,
                       const std::vector<std::string>& array_ids, doa::NodeStatus& out) {
  const std::string_view id = bounded_view(sample.array_id);
  if (id.empty()) return SampleProblem::empty_key;
  if (index_of(id, array_ids) < 0) return SampleProblem::unknown_array;
  if (!finite(sample.sample_rate_hz) || !finite(sample.level_dbfs) ||
      !finite(sample.noise_floor_dbfs) || !finite(sample.snr_db) ||
      !finite(sample.closure_residual_us) || !finite(sample.fit_residual_us)) {
    return SampleProblem::non_finite;
  }
  if (absurd(sample.time_ns)) return SampleProblem::absurd_time;
  if (!(sample.closure_residual_us >= 0.0 &&
        sample.closure_residual_us <= doa::kMaxHealthDelay_us) ||
      !(sample.fit_residual_us >= 0.0 && sample.fit_residual_us <= doa::kMaxHealthDelay_us))
    return SampleProblem::bad_value;
  if (sample.sample_rate_hz < 0.0 || sample.overruns < 0 || sample.dropouts < 0 ||
      sample.clipped_samples < 0 || sample.non_finite_samples < 0 || sample.incident_clips < 0 ||
      sample.incident_write_errors < 0 || sample.channel_count > doa::kMaxStatusChannels) {
    return SampleProblem::bad_value;
  }
  constexpr unsigned kKnownProblems = (1U << doa::kHealthProblemCount) - 1U;
  for (std::size_t c = 0; c < sample.channel_count; ++c) {
    const dronetrack_ChannelHealth& channel = sample.channels[c];
    if (!finite(channel.rms_dbfs) || !finite(channel.level_offset_db) ||
        !finite(channel.delay_offset_us) || !finite(channel.delay_std_us))
      return SampleProblem::non_finite;
    if (channel.non_finite_samples < 0 || channel.clipped_samples < 0 ||
        (channel.problems & ~kKnownProblems) != 0 ||
        (channel.problems_seen & ~kKnownProblems) != 0 ||
        (channel.array_problems & ~doa::kKnownArrayProblems) != 0 ||
        (channel.array_problems_seen & ~doa::kKnownArrayProblems) != 0 ||
        std::fabs(channel.level_offset_db) > doa::kMaxLevelOffset_db ||
        std::fabs(channel.delay_offset_us) > doa::kMaxHealthDelay_us ||
        !(channel.delay_std_us >= 0.0 && channel.delay_std_us <= doa::kMaxHealthDelay_us))
      return SampleProblem::bad_value;
  }
  out.array_id.assign(id);
  out.time_s = ns_to_seconds(sample.time_ns);
  out.alive = sample.alive;
  out.sample_rate_hz = sample.sample_rate_hz;
  out.overruns = sample.overruns;
  out.dropouts = sample.dropouts;
  out.clipped_samples = sample.clipped_samples;
  out.non_finite_samples = sample.non_finite_samples;
  out.level_dbfs = sample.level_dbfs;
  out.noise_floor_dbfs = sample.noise_floor_dbfs;
  out.snr_db = sample.snr_db;
  out.detecting = sample.detecting;
  out.closure_residual_us = sample.closure_residual_us;
  out.fit_residual_us = sample.fit_residual_us;
  out.software_version.assign(bounded_view(sample.software_version));
  out.incident_clips = sample.incident_clips;
  out.incident_write_errors = sample.incident_write_errors;
  out.channels.clear();
  for (std::size_t c = 0; c < sample.channel_count; ++c) {
    const dronetrack_ChannelHealth& channel = sample.channels[c];
    out.channels.push_back({channel.problems, channel.problems_seen, channel.non_finite_samples,
                            channel.clipped_samples, channel.rms_dbfs, channel.array_problems,
                            channel.array_problems_seen, channel.level_offset_db,
                            channel.delay_offset_us, channel.delay_std_us});
  }
  return SampleProblem::none;
}

// ---- Track ----

void to_idl(const fusion::TrackReport& report, dronetrack_Track& sample) {
  sample.id = report.id;
  sample.time_ns = seconds_to_ns(report.time_s);
  put_vector3(report.position_m, sample.position_m);
  put_vector3(report.velocity_mps, sample.velocity_mps);
  put_vector3(report.acceleration_mps2, sample.acceleration_mps2);
  std::size_t k = 0;
  for (int row = 0; row < 9; ++row) {
    for (int column = row; column < 9; ++column) {
      sample.covariance_upper[k++] = report.covariance(row, column);
    }
  }
  sample.status = static_cast<std::uint8_t>(report.status);
  sample.contributing_arrays = report.contributing_arrays;
  sample.last_update_ns = seconds_to_ns(report.last_update_s);
  sample.track_class = static_cast<std::uint8_t>(report.track_class);
  sample.class_confidence = report.class_confidence;
  sample.one_array = report.one_array;
  sample.hypotheses = report.hypotheses;
}

SampleProblem from_idl(const dronetrack_Track& sample, fusion::TrackReport& out) {
  if (!all_finite(sample.position_m) || !all_finite(sample.velocity_mps) ||
      !all_finite(sample.acceleration_mps2) || !all_finite(sample.covariance_upper)) {
    return SampleProblem::non_finite;
  }
  if (sample.status > 2 || sample.track_class > 3 || !finite(sample.class_confidence) ||
      sample.hypotheses < 0)
    return SampleProblem::bad_value;
  out.id = sample.id;
  out.time_s = ns_to_seconds(sample.time_ns);
  out.position_m = vector3(sample.position_m);
  out.velocity_mps = vector3(sample.velocity_mps);
  out.acceleration_mps2 = vector3(sample.acceleration_mps2);
  std::size_t k = 0;
  for (int row = 0; row < 9; ++row) {
    for (int column = row; column < 9; ++column) {
      out.covariance(row, column) = sample.covariance_upper[k];
      out.covariance(column, row) = sample.covariance_upper[k];
      ++k;
    }
  }
  out.status = static_cast<fusion::TrackStatus>(sample.status);
  out.contributing_arrays = sample.contributing_arrays;
  out.last_update_s = ns_to_seconds(sample.last_update_ns);
  out.track_class = static_cast<fusion::TrackClass>(sample.track_class);
  out.class_confidence = sample.class_confidence;
  out.one_array = sample.one_array;
  out.hypotheses = std::max(1, static_cast<int>(sample.hypotheses));  // 0: a zeroed sample
  return SampleProblem::none;
}

// ---- Alert ----

void to_idl(const fusion::ZoneEvent& event, dronetrack_Alert& sample) {
  copy_bounded(sample.zone, event.zone);
  sample.track_id = event.track_id;
  sample.entered = event.entered;
  sample.time_ns = seconds_to_ns(event.time_s);
  put_vector3(event.position_m, sample.position_m);
  sample.event = static_cast<std::uint8_t>(fusion::kind_of(event));
  sample.track_class = static_cast<std::uint8_t>(event.track_class);
  sample.previous_class = static_cast<std::uint8_t>(event.previous_class);
}

SampleProblem from_idl(const dronetrack_Alert& sample, fusion::ZoneEvent& out) {
  const std::string_view zone = bounded_view(sample.zone);
  if (sample.event > 2 || sample.track_class > 3 || sample.previous_class > 3)
    return SampleProblem::bad_value;
  const auto kind = static_cast<fusion::ZoneEventKind>(sample.event);
  if (zone.empty() && kind != fusion::ZoneEventKind::class_changed) return SampleProblem::empty_key;
  if (!all_finite(sample.position_m)) return SampleProblem::non_finite;
  out.zone.assign(zone);
  out.track_id = sample.track_id;
  out.entered = sample.entered;
  out.kind = kind;
  out.track_class = static_cast<fusion::TrackClass>(sample.track_class);
  out.previous_class = static_cast<fusion::TrackClass>(sample.previous_class);
  out.time_s = ns_to_seconds(sample.time_ns);
  out.position_m = vector3(sample.position_m);
  return SampleProblem::none;
}

static_assert(kArrayIdBound == 65, "string<64> maps to char[65]");

}  // namespace dronetrack::dds
