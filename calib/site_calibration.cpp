#include "calib/site_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <optional>
#include <sstream>

#include <ceres/ceres.h>
#include <ceres/normal_prior.h>
#include <Eigen/Dense>

#include "calib/tdoa_model.hpp"
#include "common/statistics.hpp"

namespace dronetrack::calib {
namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;
constexpr std::size_t kMaxMics = 8;  // as doa::kMaxPairs (28 pairs)
// How far from the initial channel delays a frame's pair delays may be for the first solve:
// wide enough for the uncalibrated geometry (a 2 degree yaw: 50 us on a 0.8 m pair) and the GPS
// error at close range, narrow against the ~400 us between cycles of a 1.5-3.5 kHz band.
constexpr double kInitialGate_s = 150e-6;
// Consistency factor of the median absolute deviation for a Gaussian.
constexpr double kMadToStd = 1.4826;

// The unknowns of one array, as corrections to its nominal values: the storage Ceres works on.
struct ArrayUnknowns {
  std::array<double, 3> attitude_rad{};  // yaw, pitch, roll corrections
  std::array<double, 3> position_m{};    // site frame
  std::vector<double> mic_offsets_m;     // 3 per mic, array frame
  std::vector<double> delays_s;          // per mic; [0] held at 0
  double clock_s = 0.0;
  double ground_echo_pull = 0.0;
};

// One frame's residuals, whitened: (predicted - measured) / tdoa_std. The source is where the
// two bracketing reference positions put it at the emission time solved at the current clock
// offset; a change of the clock offset moves it back along the smoothed velocity (exact at
// convergence: the outer loop re-solves the emission time at the new clock).
struct TdoaResidual {
  const ArrayNominal* array = nullptr;
  std::vector<double> measured_s;
  double weight = 0.0;  // of the upper sample at the emission time
  Eigen::Vector3d velocity_mps = Eigen::Vector3d::Zero();
  double clock_linearised_s = 0.0;
  double inverse_std = 1.0;
  double speed_of_sound_mps = 343.0;
  const std::vector<std::array<double, 2>>* bands_hz = nullptr;

  // parameters: attitude(3), position(3), mic offsets(3n), delays(n), clock(1), lower(3),
  // upper(3), ground-echo pull(1)
  template <class T>
  bool operator()(T const* const* parameters, T* residuals) const {
    const T* attitude = parameters[0];
    const T* position = parameters[1];
    const T* offsets = parameters[2];
    const T* delays = parameters[3];
    const T* clock = parameters[4];
    const T* lower = parameters[5];
    const T* upper = parameters[6];
    const std::size_t mics = array->mics_m.size();
    const T yaw = T(array->yaw_deg * kRadPerDeg) + attitude[0];
    const T pitch = T(array->pitch_deg * kRadPerDeg) + attitude[1];
    const T roll = T(array->roll_deg * kRadPerDeg) + attitude[2];
    std::array<T, 3 * kMaxMics> mic_site;
    for (std::size_t i = 0; i < mics; ++i) {
      const T in_array[3] = {T(array->mics_m[i].x()) + offsets[3 * i],
                             T(array->mics_m[i].y()) + offsets[3 * i + 1],
                             T(array->mics_m[i].z()) + offsets[3 * i + 2]};
      rotate_array_to_site(yaw, pitch, roll, in_array, &mic_site[3 * i]);
      for (int axis = 0; axis < 3; ++axis)
        mic_site[3 * i + static_cast<std::size_t>(axis)] +=
            T(array->position_m(axis)) + position[axis];
    }
    const T clock_change = clock[0] - T(clock_linearised_s);
    T source[3];
    for (int axis = 0; axis < 3; ++axis)
      source[axis] = lower[axis] + T(weight) * (upper[axis] - lower[axis]) -
                     T(velocity_mps(axis)) * clock_change;
    std::array<T, kMaxMics*(kMaxMics - 1) / 2> predicted;
    predict_tdoas(source, mic_site.data(), delays, mics, speed_of_sound_mps, predicted.data());
    if (bands_hz != nullptr && !bands_hz->empty()) {
      // The ground image: the source mirrored in the ground, heard through the same channels.
      const T image[3] = {source[0], source[1], T(2.0 * array->ground_height_m) - source[2]};
      std::array<T, kMaxMics*(kMaxMics - 1) / 2> mirrored;
      predict_tdoas(image, mic_site.data(), delays, mics, speed_of_sound_mps, mirrored.data());
      for (std::size_t p = 0; p < measured_s.size(); ++p)
        predicted[p] += parameters[7][0] *
                        peak_pull_s(mirrored[p] - predicted[p], bands_hz->data(), bands_hz->size());
    }
    for (std::size_t p = 0; p < measured_s.size(); ++p)
      residuals[p] = (predicted[p] - T(measured_s[p])) * T(inverse_std);
    return true;
  }
};

std::string frame_name(const std::vector<ArrayNominal>& arrays, const TdoaFrame& frame,
                       std::size_t index) {
  std::ostringstream out;
  out << "TDOA frame " << index << " (array "
      << (frame.array >= 0 && static_cast<std::size_t>(frame.array) < arrays.size()
              ? arrays[static_cast<std::size_t>(frame.array)].id
              : std::string("?"))
      << ", t = " << frame.time_s << " s)";
  return out.str();
}

void check_input(const std::vector<ArrayNominal>& arrays, const std::vector<TdoaFrame>& frames,
                 const ReferenceTrack& reference, const CalibrationSettings& settings) {
  if (arrays.empty()) throw CalibrationError("no arrays to calibrate");
  for (const auto& array : arrays) {
    const std::size_t mics = array.mics_m.size();
    if (mics < 2 || mics > kMaxMics)
      throw CalibrationError("array " + array.id + ": " + std::to_string(mics) +
                             " mics; the calibration takes 2 to 8");
    bool finite = array.position_m.allFinite() && std::isfinite(array.yaw_deg) &&
                  std::isfinite(array.pitch_deg) && std::isfinite(array.roll_deg) &&
                  std::isfinite(array.mic_position_std_m) && array.mic_position_std_m >= 0.0;
    for (const auto& mic : array.mics_m) finite = finite && mic.allFinite();
    if (!finite) throw CalibrationError("array " + array.id + ": a non-finite nominal value");
  }
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const TdoaFrame& frame = frames[k];
    if (frame.array < 0 || static_cast<std::size_t>(frame.array) >= arrays.size())
      throw CalibrationError(frame_name(arrays, frame, k) + ": no such array");
    const std::size_t mics = arrays[static_cast<std::size_t>(frame.array)].mics_m.size();
    if (frame.tdoa_s.size() != mics * (mics - 1) / 2)
      throw CalibrationError(frame_name(arrays, frame, k) + ": " +
                             std::to_string(frame.tdoa_s.size()) + " pair delays for " +
                             std::to_string(mics) + " mics");
    bool finite = std::isfinite(frame.time_s);
    for (double tdoa : frame.tdoa_s) finite = finite && std::isfinite(tdoa);
    if (!finite) throw CalibrationError(frame_name(arrays, frame, k) + ": a non-finite value");
  }
  for (std::size_t i = 0; i < reference.samples().size(); ++i) {
    if (!reference.samples()[i].position_m.allFinite() ||
        !std::isfinite(reference.samples()[i].time_s))
      throw CalibrationError("reference sample " + std::to_string(i) + ": a non-finite value");
  }
  const CalibrationPriors& priors = settings.priors;
  for (double value :
       {priors.attitude_std_deg, priors.array_position_std_m, priors.channel_delay_std_s,
        priors.clock_offset_std_s, settings.reference_position_std_m, settings.tdoa_std_s}) {
    if (!(std::isfinite(value) && value >= 0.0))
      throw CalibrationError("a prior std is negative or not finite");
  }
}

// A frame placed on the reference track: its emission time and bracket.
struct PlacedFrame {
  std::size_t frame = 0;
  double emission_s = 0.0;
  ReferenceBracket bracket;
  Eigen::Vector3d velocity_mps = Eigen::Vector3d::Zero();
};

Eigen::Vector3d calibrated_centre(const ArrayNominal& array, const ArrayUnknowns& unknowns) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < array.mics_m.size(); ++i)
    sum += array.mics_m[i] + Eigen::Vector3d(unknowns.mic_offsets_m[3 * i],
                                             unknowns.mic_offsets_m[3 * i + 1],
                                             unknowns.mic_offsets_m[3 * i + 2]);
  const double in[3] = {sum.x() / static_cast<double>(array.mics_m.size()),
                        sum.y() / static_cast<double>(array.mics_m.size()),
                        sum.z() / static_cast<double>(array.mics_m.size())};
  double out[3];
  rotate_array_to_site((array.yaw_deg * kRadPerDeg) + unknowns.attitude_rad[0],
                       (array.pitch_deg * kRadPerDeg) + unknowns.attitude_rad[1],
                       (array.roll_deg * kRadPerDeg) + unknowns.attitude_rad[2], in, out);
  return array.position_m +
         Eigen::Vector3d(unknowns.position_m[0], unknowns.position_m[1], unknowns.position_m[2]) +
         Eigen::Vector3d(out[0], out[1], out[2]);
}

std::vector<PlacedFrame> place_frames(const std::vector<ArrayNominal>& arrays,
                                      const std::vector<TdoaFrame>& frames,
                                      const std::vector<ArrayUnknowns>& unknowns,
                                      const ReferenceTrack& reference,
                                      const std::vector<Eigen::Vector3d>& positions,
                                      double speed_of_sound_mps) {
  std::vector<PlacedFrame> placed;
  placed.reserve(frames.size());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const auto a = static_cast<std::size_t>(frames[k].array);
    const Eigen::Vector3d listener = calibrated_centre(arrays[a], unknowns[a]);
    const auto emission = reference.emission_time_s(frames[k].time_s - unknowns[a].clock_s,
                                                    listener, speed_of_sound_mps, positions);
    if (!emission) continue;
    const auto bracket = reference.bracket(*emission);
    if (!bracket) continue;
    placed.push_back({k, *emission, *bracket, reference.velocity_mps(*emission, 1.0)});
  }
  return placed;
}

TdoaResidual make_residual(const ArrayNominal& array, const TdoaFrame& frame,
                           const PlacedFrame& placed, double clock_s, double tdoa_std_s,
                           double speed_of_sound_mps,
                           const std::vector<std::array<double, 2>>& bands_hz) {
  TdoaResidual residual;
  residual.array = &array;
  residual.measured_s = frame.tdoa_s;
  residual.weight = placed.bracket.weight;
  residual.velocity_mps = placed.velocity_mps;
  residual.clock_linearised_s = clock_s;
  residual.inverse_std = 1.0 / tdoa_std_s;
  residual.speed_of_sound_mps = speed_of_sound_mps;
  residual.bands_hz = &bands_hz;
  return residual;
}

// Unwhitened residuals (s) of every placed frame at the current unknowns.
std::vector<std::vector<double>> frame_residuals(const std::vector<ArrayNominal>& arrays,
                                                 const std::vector<TdoaFrame>& frames,
                                                 const std::vector<PlacedFrame>& placed,
                                                 const std::vector<ArrayUnknowns>& unknowns,
                                                 const std::vector<Eigen::Vector3d>& positions,
                                                 const CalibrationSettings& settings) {
  std::vector<std::vector<double>> out;
  out.reserve(placed.size());
  for (const auto& place : placed) {
    const TdoaFrame& frame = frames[place.frame];
    const auto a = static_cast<std::size_t>(frame.array);
    const TdoaResidual residual = make_residual(arrays[a], frame, place, unknowns[a].clock_s, 1.0,
                                                settings.speed_of_sound_mps, settings.bands_hz);
    const auto lower = static_cast<std::size_t>(place.bracket.index);
    const double* parameters[8] = {unknowns[a].attitude_rad.data(),
                                   unknowns[a].position_m.data(),
                                   unknowns[a].mic_offsets_m.data(),
                                   unknowns[a].delays_s.data(),
                                   &unknowns[a].clock_s,
                                   positions[lower].data(),
                                   positions[lower + 1].data(),
                                   &unknowns[a].ground_echo_pull};
    std::vector<double> values(frame.tdoa_s.size());
    residual(parameters, values.data());
    out.push_back(std::move(values));
  }
  return out;
}

// The centre of the densest `width_s` window of `values`: the median of the values in it. When
// a channel's skew makes the GCC take a wrong cycle of the rotor's harmonic on many frames, the
// right cycle is still the largest cluster, though not always half of the frames.
double densest_cluster_centre(std::vector<double> values, double width_s) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  std::size_t best_first = 0, best_count = 0, last = 0;
  for (std::size_t first = 0; first < values.size(); ++first) {
    last = std::max(last, first);
    while (last + 1 < values.size() && values[last + 1] - values[first] <= width_s) ++last;
    if (last + 1 - first > best_count) {
      best_count = last + 1 - first;
      best_first = first;
    }
  }
  return values[best_first + best_count / 2];
}

// Starts each array's channel delays where its pair residuals at the nominal geometry cluster.
// From zero delays, a skew of 0.2-0.3 ms leaves the robust loss a local minimum that fits half
// the frames with a mic moved centimetres (field-error seeds 18 and 19); the geometry's own
// errors (a 2 degree yaw, millimetres of mic offset, the GPS error) spread the right cluster's
// residuals over tens of microseconds only.
void initialise_delays(const std::vector<ArrayNominal>& arrays,
                       const std::vector<TdoaFrame>& frames, const std::vector<PlacedFrame>& placed,
                       const std::vector<std::vector<double>>& residuals,
                       std::vector<ArrayUnknowns>& unknowns) {
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    const std::size_t mics = arrays[a].mics_m.size();
    const std::size_t pairs = mics * (mics - 1) / 2;
    std::vector<std::vector<double>> per_pair(pairs);
    for (std::size_t k = 0; k < placed.size(); ++k) {
      if (static_cast<std::size_t>(frames[placed[k].frame].array) != a) continue;
      for (std::size_t p = 0; p < pairs; ++p) per_pair[p].push_back(residuals[k][p]);
    }
    if (per_pair[0].empty()) continue;
    // residual_ij = predicted - measured, so the delays' correction has d_i - d_j = -centre_ij;
    // channel 0 held, least squares over every pair.
    Eigen::MatrixXd design = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(pairs),
                                                   static_cast<Eigen::Index>(mics - 1));
    Eigen::VectorXd target(static_cast<Eigen::Index>(pairs));
    std::size_t p = 0;
    for (std::size_t i = 0; i < mics; ++i) {
      for (std::size_t j = i + 1; j < mics; ++j, ++p) {
        const auto row = static_cast<Eigen::Index>(p);
        if (i > 0) design(row, static_cast<Eigen::Index>(i - 1)) = 1.0;
        design(row, static_cast<Eigen::Index>(j - 1)) = -1.0;
        target(row) = -densest_cluster_centre(per_pair[p], kInitialGate_s);
      }
    }
    const Eigen::VectorXd correction = design.colPivHouseholderQr().solve(target);
    for (std::size_t i = 1; i < mics; ++i)
      unknowns[a].delays_s[i] += correction(static_cast<Eigen::Index>(i - 1));
  }
}

ResidualStats stats_of(const std::vector<std::vector<double>>& residuals,
                       const std::vector<PlacedFrame>& placed, const std::vector<TdoaFrame>& frames,
                       int array) {
  std::vector<double> magnitudes;
  double sum_squares = 0.0;
  for (std::size_t k = 0; k < residuals.size(); ++k) {
    if (array >= 0 && frames[placed[k].frame].array != array) continue;
    for (double value : residuals[k]) {
      magnitudes.push_back(std::abs(value));
      sum_squares += value * value;
    }
  }
  ResidualStats stats;
  stats.count = static_cast<int>(magnitudes.size());
  if (stats.count == 0) return stats;
  stats.rms_s = std::sqrt(sum_squares / stats.count);
  stats.median_abs_s = median(std::move(magnitudes));
  return stats;
}

// Greedy count of directions (from the array's nominal centre to the source) at least
// `separation_deg` apart; stops counting at `enough`.
int distinct_directions(const ArrayNominal& array, const std::vector<TdoaFrame>& frames,
                        const std::vector<PlacedFrame>& placed, int array_index,
                        const ReferenceTrack& reference,
                        const std::vector<Eigen::Vector3d>& positions, double separation_deg,
                        int enough) {
  const ArrayUnknowns zero{{}, {}, std::vector<double>(3 * array.mics_m.size(), 0.0), {}, 0.0};
  const Eigen::Vector3d centre = calibrated_centre(array, zero);
  const double cos_separation = std::cos(separation_deg * kRadPerDeg);
  std::vector<Eigen::Vector3d> kept;
  for (const auto& place : placed) {
    if (frames[place.frame].array != array_index) continue;
    const Eigen::Vector3d offset = reference.position_at(place.bracket, positions) - centre;
    if (offset.norm() < 1e-6) continue;
    const Eigen::Vector3d direction = offset.normalized();
    const bool is_new = std::all_of(kept.begin(), kept.end(), [&](const Eigen::Vector3d& other) {
      return direction.dot(other) < cos_separation;
    });
    if (is_new) kept.push_back(direction);
    if (static_cast<int>(kept.size()) >= enough) break;
  }
  return static_cast<int>(kept.size());
}

// A Gaussian prior on a whole block: residual = (x - mean) / std, per coordinate.
ceres::CostFunction* prior_on(const Eigen::VectorXd& mean, const Eigen::VectorXd& std) {
  const Eigen::VectorXd inverse = std.cwiseInverse();
  const ceres::Matrix weights = inverse.asDiagonal();
  return new ceres::NormalPrior(weights, mean);
}

Estimate make_estimate(double nominal, double value, double variance, double prior_std,
                       double excited_ratio) {
  Estimate estimate;
  estimate.nominal = nominal;
  estimate.value = value;
  estimate.std = std::sqrt(std::max(0.0, variance));
  estimate.prior_std = prior_std;
  estimate.excited = prior_std > 0.0 && estimate.std < excited_ratio * prior_std;
  return estimate;
}

// The problem at one linearisation (emission times, TDOA std): built, solved, and kept for the
// covariance.
struct Solve {
  std::unique_ptr<ceres::Problem> problem;
  std::string report;
};

enum class Loss { huber, cauchy };

// The frames whose every residual is within `limit_s`.
std::vector<PlacedFrame> inliers(const std::vector<PlacedFrame>& placed,
                                 const std::vector<std::vector<double>>& residuals,
                                 double limit_s) {
  std::vector<PlacedFrame> out;
  for (std::size_t k = 0; k < placed.size(); ++k) {
    const bool inside = std::all_of(residuals[k].begin(), residuals[k].end(),
                                    [&](double value) { return std::abs(value) <= limit_s; });
    if (inside) out.push_back(placed[k]);
  }
  return out;
}

// The priors' means as corrections to `nominal`: where `centre` is, seen from `nominal`.
ArrayUnknowns prior_mean(const ArrayNominal& nominal, const ArrayNominal& centre) {
  ArrayUnknowns mean;
  mean.attitude_rad = {(centre.yaw_deg - nominal.yaw_deg) * kRadPerDeg,
                       (centre.pitch_deg - nominal.pitch_deg) * kRadPerDeg,
                       (centre.roll_deg - nominal.roll_deg) * kRadPerDeg};
  for (int axis = 0; axis < 3; ++axis)
    mean.position_m[static_cast<std::size_t>(axis)] =
        centre.position_m(axis) - nominal.position_m(axis);
  const auto delay = [](const ArrayNominal& array, std::size_t i) {
    return i < array.channel_delay_s.size() ? array.channel_delay_s[i] : 0.0;
  };
  for (std::size_t i = 0; i < nominal.mics_m.size(); ++i) {
    for (int axis = 0; axis < 3; ++axis)
      mean.mic_offsets_m.push_back(centre.mics_m[i](axis) - nominal.mics_m[i](axis));
    mean.delays_s.push_back((delay(centre, i) - delay(centre, 0)) -
                            (delay(nominal, i) - delay(nominal, 0)));
  }
  mean.clock_s = centre.clock_offset_s - nominal.clock_offset_s;
  return mean;
}

Solve solve_once(const std::vector<ArrayNominal>& arrays, const std::vector<TdoaFrame>& frames,
                 const std::vector<PlacedFrame>& placed, std::vector<ArrayUnknowns>& unknowns,
                 const std::vector<ArrayUnknowns>& prior_means, const ReferenceTrack& reference,
                 std::vector<Eigen::Vector3d>& positions, const CalibrationSettings& settings,
                 double tdoa_std_s, Loss loss) {
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::TAKE_OWNERSHIP;
  Solve solve;
  solve.problem = std::make_unique<ceres::Problem>(problem_options);
  ceres::Problem& problem = *solve.problem;
  const CalibrationPriors& priors = settings.priors;

  for (std::size_t a = 0; a < arrays.size(); ++a) {
    ArrayUnknowns& u = unknowns[a];
    const std::size_t mics = arrays[a].mics_m.size();
    problem.AddParameterBlock(u.attitude_rad.data(), 3);
    problem.AddParameterBlock(u.position_m.data(), 3);
    problem.AddParameterBlock(u.mic_offsets_m.data(), static_cast<int>(3 * mics));
    problem.AddParameterBlock(u.delays_s.data(), static_cast<int>(mics),
                              new ceres::SubsetManifold(static_cast<int>(mics), {0}));
    problem.AddParameterBlock(&u.clock_s, 1);
    problem.AddParameterBlock(&u.ground_echo_pull, 1);
    const ArrayUnknowns& mean = prior_means[a];
    const auto add_prior = [&](double* block, const double* centre, int size, double std) {
      if (std <= 0.0) {
        problem.SetParameterBlockConstant(block);
        return;
      }
      problem.AddResidualBlock(prior_on(Eigen::Map<const Eigen::VectorXd>(centre, size),
                                        Eigen::VectorXd::Constant(size, std)),
                               nullptr, block);
    };
    add_prior(u.attitude_rad.data(), mean.attitude_rad.data(), 3,
              priors.attitude_std_deg * kRadPerDeg);
    add_prior(u.position_m.data(), mean.position_m.data(), 3, priors.array_position_std_m);
    add_prior(u.mic_offsets_m.data(), mean.mic_offsets_m.data(), static_cast<int>(3 * mics),
              arrays[a].mic_position_std_m);
    add_prior(u.delays_s.data(), mean.delays_s.data(), static_cast<int>(mics),
              priors.channel_delay_std_s);
    add_prior(&u.clock_s, &mean.clock_s, 1, priors.clock_offset_std_s);
    add_prior(&u.ground_echo_pull, &mean.ground_echo_pull, 1,
              settings.bands_hz.empty() ? 0.0 : priors.ground_echo_pull_std);
  }

  std::vector<bool> used(positions.size(), false);
  for (const auto& place : placed) {
    const TdoaFrame& frame = frames[place.frame];
    const auto a = static_cast<std::size_t>(frame.array);
    ArrayUnknowns& u = unknowns[a];
    const auto lower = static_cast<std::size_t>(place.bracket.index);
    auto* cost = new ceres::DynamicAutoDiffCostFunction<TdoaResidual, 8>(
        new TdoaResidual(make_residual(arrays[a], frame, place, u.clock_s, tdoa_std_s,
                                       settings.speed_of_sound_mps, settings.bands_hz)));
    const std::size_t mics = arrays[a].mics_m.size();
    for (int size : {3, 3, static_cast<int>(3 * mics), static_cast<int>(mics), 1, 3, 3, 1})
      cost->AddParameterBlock(size);
    cost->SetNumResiduals(static_cast<int>(frame.tdoa_s.size()));
    const std::vector<double*> blocks = {
        u.attitude_rad.data(),       u.position_m.data(), u.mic_offsets_m.data(),
        u.delays_s.data(),           &u.clock_s,          positions[lower].data(),
        positions[lower + 1].data(), &u.ground_echo_pull};
    ceres::LossFunction* robust =
        loss == Loss::huber
            ? static_cast<ceres::LossFunction*>(new ceres::HuberLoss(settings.huber_threshold))
            : new ceres::CauchyLoss(settings.huber_threshold);
    problem.AddResidualBlock(cost, robust, blocks);
    used[lower] = used[lower + 1] = true;
  }
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (!used[i]) continue;
    if (settings.reference_position_std_m <= 0.0) {
      problem.SetParameterBlockConstant(positions[i].data());
      continue;
    }
    problem.AddResidualBlock(prior_on(reference.samples()[i].position_m,
                                      Eigen::Vector3d::Constant(settings.reference_position_std_m)),
                             nullptr, positions[i].data());
  }

  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.max_num_iterations = 100;
  options.num_threads = 1;  // the machine's cores belong to the nodes
  options.logging_type = ceres::SILENT;
  options.function_tolerance = 1e-10;
  options.parameter_tolerance = 1e-12;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (!summary.IsSolutionUsable()) throw CalibrationError("the solver failed: " + summary.message);
  solve.report = summary.BriefReport();
  return solve;
}

// How much the residuals of neighbouring frames share: per array and pair, the residual series
// in time order, its autocorrelation summed over the lags while it stays significant
// (above 2 / sqrt(n)); 1 + 2 * that sum, weighted over all series. Outliers (beyond the Huber
// threshold) count as zero, as the fit all but leaves them out.
double correlation_inflation(const std::vector<std::vector<double>>& residuals,
                             const std::vector<PlacedFrame>& placed,
                             const std::vector<TdoaFrame>& frames, double tdoa_std_s,
                             double huber_threshold) {
  constexpr std::size_t kMaxLag = 40;
  std::vector<std::size_t> order(placed.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
  const auto array_of = [&](std::size_t k) { return frames[placed[k].frame].array; };
  std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
    if (array_of(x) != array_of(y)) return array_of(x) < array_of(y);
    return frames[placed[x].frame].time_s < frames[placed[y].frame].time_s;
  });
  double weighted = 0.0, weights = 0.0;
  for (std::size_t begin = 0, end = 0; begin < order.size(); begin = end) {
    end = begin;
    while (end < order.size() && array_of(order[end]) == array_of(order[begin])) ++end;
    for (std::size_t p = 0; p < residuals[order[begin]].size(); ++p) {
      std::vector<double> series;
      for (std::size_t k = begin; k < end; ++k) {
        const double value = residuals[order[k]][p];
        series.push_back(std::abs(value) <= huber_threshold * tdoa_std_s ? value : 0.0);
      }
      if (series.size() < 10) continue;
      const auto n = static_cast<double>(series.size());
      double mean = 0.0;
      for (double value : series) mean += value / n;
      double variance = 0.0;
      for (double& value : series) {
        value -= mean;
        variance += value * value;
      }
      if (!(variance > 0.0)) continue;
      double sum = 0.0;
      for (std::size_t lag = 1; lag <= kMaxLag && lag < series.size(); ++lag) {
        double covariance = 0.0;
        for (std::size_t k = lag; k < series.size(); ++k) covariance += series[k] * series[k - lag];
        const double rho = covariance / variance;
        if (rho < 2.0 / std::sqrt(n)) break;
        sum += rho;
      }
      weighted += n * (1.0 + 2.0 * sum);
      weights += n;
    }
  }
  return weights > 0.0 ? std::max(1.0, weighted / weights) : 1.0;
}

// Free scalars the TDOA residuals see: the arrays' unknowns and the reference positions.
int free_parameters(const Solve& solve, const std::vector<ArrayNominal>& arrays,
                    std::vector<ArrayUnknowns>& unknowns, std::vector<Eigen::Vector3d>& positions) {
  int count = 0;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    for (double* block : {unknowns[a].attitude_rad.data(), unknowns[a].position_m.data(),
                          unknowns[a].mic_offsets_m.data(), unknowns[a].delays_s.data(),
                          &unknowns[a].clock_s, &unknowns[a].ground_echo_pull}) {
      if (!solve.problem->IsParameterBlockConstant(block))
        count += solve.problem->ParameterBlockTangentSize(block);
    }
  }
  for (auto& position : positions) {
    if (solve.problem->HasParameterBlock(position.data()) &&
        !solve.problem->IsParameterBlockConstant(position.data()))
      count += 3;
  }
  return count;
}

}  // namespace

CalibrationResult calibrate_site(const std::vector<ArrayNominal>& arrays,
                                 const std::vector<TdoaFrame>& frames,
                                 const ReferenceTrack& reference,
                                 const CalibrationSettings& settings,
                                 const std::vector<ArrayNominal>* prior_centres) {
  check_input(arrays, frames, reference, settings);
  if (prior_centres != nullptr) {
    bool matching = prior_centres->size() == arrays.size();
    for (std::size_t a = 0; matching && a < arrays.size(); ++a)
      matching = (*prior_centres)[a].mics_m.size() == arrays[a].mics_m.size();
    if (!matching) throw CalibrationError("the prior centres do not match the arrays");
  }
  const auto centre_of = [&](std::size_t a) -> const ArrayNominal& {
    return prior_centres != nullptr ? (*prior_centres)[a] : arrays[a];
  };
  std::vector<ArrayUnknowns> prior_means;
  for (std::size_t a = 0; a < arrays.size(); ++a)
    prior_means.push_back(prior_mean(arrays[a], centre_of(a)));
  std::vector<ArrayUnknowns> unknowns(arrays.size());
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    unknowns[a].mic_offsets_m.assign(3 * arrays[a].mics_m.size(), 0.0);
    unknowns[a].delays_s.assign(arrays[a].mics_m.size(), 0.0);
  }
  std::vector<Eigen::Vector3d> positions;
  for (const auto& sample : reference.samples()) positions.push_back(sample.position_m);

  CalibrationResult result;
  std::vector<PlacedFrame> placed =
      place_frames(arrays, frames, unknowns, reference, positions, settings.speed_of_sound_mps);
  if (placed.empty()) {
    double first = 0.0, last = 0.0;
    if (!frames.empty()) {
      const auto [low, high] = std::minmax_element(
          frames.begin(), frames.end(),
          [](const TdoaFrame& x, const TdoaFrame& y) { return x.time_s < y.time_s; });
      first = low->time_s;
      last = high->time_s;
    }
    std::ostringstream out;
    out << "no TDOA frame falls on the reference track (reference t = " << reference.start_s()
        << ".." << reference.end_s() << " s; ";
    if (frames.empty()) {
      out << "no TDOA frames at all)";
    } else {
      out << "TDOA frames t = " << first << ".." << last << " s)";
    }
    throw CalibrationError(out.str());
  }
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    const int directions = distinct_directions(
        arrays[a], frames, placed, static_cast<int>(a), reference, positions,
        settings.min_direction_separation_deg, settings.min_distinct_directions);
    if (directions < settings.min_distinct_directions) {
      std::ostringstream out;
      out << "array " << arrays[a].id << ": the reference is heard from " << directions
          << " distinct direction" << (directions == 1 ? "" : "s") << "; at least "
          << settings.min_distinct_directions << ", each " << settings.min_direction_separation_deg
          << " degrees from the others, are needed (fly around the array)";
      throw CalibrationError(out.str());
    }
  }

  const auto before = frame_residuals(arrays, frames, placed, unknowns, positions, settings);
  result.before = stats_of(before, placed, frames, -1);
  std::vector<ResidualStats> before_per_array;
  for (std::size_t a = 0; a < arrays.size(); ++a)
    before_per_array.push_back(stats_of(before, placed, frames, static_cast<int>(a)));

  initialise_delays(arrays, frames, placed, before, unknowns);
  const auto initial_residuals =
      frame_residuals(arrays, frames, placed, unknowns, positions, settings);
  const ResidualStats initialised = stats_of(initial_residuals, placed, frames, -1);
  // The first solve sees only the frames near the initial delays: those whose GCC took another
  // cycle (about 400 us away in this band) fit the nominal geometry with zero delays, as the
  // uncorrected node chose them for, and where they are most of an array's frames they pull
  // its tilt degrees off instead (seed 18's A2: 7.5 degrees of pitch, delays back at zero).
  placed = inliers(placed, initial_residuals, kInitialGate_s);
  // The first weights come from the misfit at the initial delays (too wide: it holds the
  // geometry's errors to be found);
  // each pass re-places the frames at the new clocks and, unless given, re-estimates the TDOA
  // noise from what the calibrated model leaves.
  const bool estimate_std = settings.tdoa_std_s <= 0.0;
  double tdoa_std_s = estimate_std
                          ? std::max(1e-9, kMadToStd * std::max(initialised.median_abs_s, 1e-9))
                          : settings.tdoa_std_s;
  const auto frames_residuals_of = [&](const std::vector<PlacedFrame>& some) {
    return frame_residuals(arrays, frames, some, unknowns, positions, settings);
  };
  // Early passes use a redescending loss (Cauchy), so a frame whose GCC took the wrong cycle of
  // the rotor's harmonic (hundreds of microseconds off on every pair of one mic) pulls nothing;
  // between passes such frames (any pair beyond outlier_threshold std) are set aside, judged
  // afresh each time; the last pass is Huber on what is left.
  Solve solve;
  const int passes = estimate_std ? 4 : 2;
  int off_reference = static_cast<int>(frames.size() - placed.size());
  for (int pass = 0; pass < passes; ++pass) {
    if (pass > 0) {
      placed =
          place_frames(arrays, frames, unknowns, reference, positions, settings.speed_of_sound_mps);
      off_reference = static_cast<int>(frames.size() - placed.size());
      placed =
          inliers(placed, frames_residuals_of(placed), settings.outlier_threshold * tdoa_std_s);
    }
    const bool last = pass + 1 == passes;
    solve = solve_once(arrays, frames, placed, unknowns, prior_means, reference, positions,
                       settings, tdoa_std_s, last ? Loss::huber : Loss::cauchy);
    if (estimate_std && !last) {
      const auto residuals = frame_residuals(arrays, frames, placed, unknowns, positions, settings);
      const ResidualStats stats = stats_of(residuals, placed, frames, -1);
      // The fit absorbs part of the noise (every reference sample moves to meet the TDOAs):
      // scale by sqrt(n / (n - free parameters)), counting them all (a slight overestimate).
      const double free = static_cast<double>(free_parameters(solve, arrays, unknowns, positions));
      const double dof_factor =
          stats.count > free ? std::sqrt(stats.count / (stats.count - free)) : 1.0;
      tdoa_std_s = std::max(1e-9, kMadToStd * stats.median_abs_s * dof_factor);
    }
  }
  // Correlated frames carry less than their count: weigh them as fewer independent ones
  // (the priors keep their full weight, so no std can exceed its prior's).
  {
    const auto residuals = frame_residuals(arrays, frames, placed, unknowns, positions, settings);
    result.correlation_inflation =
        correlation_inflation(residuals, placed, frames, tdoa_std_s, settings.huber_threshold);
    if (result.correlation_inflation > 1.05) {
      solve =
          solve_once(arrays, frames, placed, unknowns, prior_means, reference, positions, settings,
                     tdoa_std_s * std::sqrt(result.correlation_inflation), Loss::huber);
    }
  }
  result.tdoa_std_s = tdoa_std_s;
  result.tdoa_std_estimated = estimate_std;
  result.solver_report = solve.report;
  result.frames_used = static_cast<int>(placed.size());
  result.frames_off_reference = off_reference;
  result.frames_rejected = static_cast<int>(frames.size() - placed.size()) - off_reference;

  ceres::Covariance::Options covariance_options;
  covariance_options.num_threads = 1;
  ceres::Covariance covariance(covariance_options);
  std::vector<std::pair<const double*, const double*>> wanted;
  for (auto& u : unknowns) {
    for (const double* block :
         {static_cast<const double*>(u.attitude_rad.data()),
          static_cast<const double*>(u.position_m.data()),
          static_cast<const double*>(u.mic_offsets_m.data()),
          static_cast<const double*>(u.delays_s.data()), static_cast<const double*>(&u.clock_s),
          static_cast<const double*>(&u.ground_echo_pull)}) {
      if (!solve.problem->IsParameterBlockConstant(const_cast<double*>(block)))
        wanted.emplace_back(block, block);
    }
  }
  if (!covariance.Compute(wanted, solve.problem.get()))
    throw CalibrationError(
        "the calibration's covariance could not be computed (a parameter no data or prior "
        "constrains)");
  const auto after = frame_residuals(arrays, frames, placed, unknowns, positions, settings);
  const auto variances = [&](const double* block, int size) {
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(size, size);
    if (!solve.problem->IsParameterBlockConstant(const_cast<double*>(block)))
      covariance.GetCovarianceBlock(block, block, out.data());
    return out.diagonal().eval();
  };

  result.after = stats_of(after, placed, frames, -1);
  std::vector<bool> used(positions.size(), false);
  for (const auto& place : placed)
    used[static_cast<std::size_t>(place.bracket.index)] =
        used[static_cast<std::size_t>(place.bracket.index) + 1] = true;
  result.reference_samples_used = static_cast<int>(std::count(used.begin(), used.end(), true));

  const CalibrationPriors& priors = settings.priors;
  const double ratio = settings.excited_ratio;
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    const ArrayNominal& nominal = arrays[a];
    const ArrayNominal& centre = centre_of(a);
    const ArrayUnknowns& u = unknowns[a];
    const std::size_t mics = nominal.mics_m.size();
    ArrayCalibration out;
    out.id = nominal.id;
    const Eigen::VectorXd attitude = variances(u.attitude_rad.data(), 3);
    const double attitude_scale = 1.0 / kRadPerDeg;
    const double attitude_prior = priors.attitude_std_deg;
    out.yaw_deg =
        make_estimate(centre.yaw_deg, nominal.yaw_deg + u.attitude_rad[0] * attitude_scale,
                      attitude(0) * attitude_scale * attitude_scale, attitude_prior, ratio);
    out.pitch_deg =
        make_estimate(centre.pitch_deg, nominal.pitch_deg + u.attitude_rad[1] * attitude_scale,
                      attitude(1) * attitude_scale * attitude_scale, attitude_prior, ratio);
    out.roll_deg =
        make_estimate(centre.roll_deg, nominal.roll_deg + u.attitude_rad[2] * attitude_scale,
                      attitude(2) * attitude_scale * attitude_scale, attitude_prior, ratio);
    const Eigen::VectorXd position = variances(u.position_m.data(), 3);
    for (int axis = 0; axis < 3; ++axis) {
      const auto index = static_cast<std::size_t>(axis);
      out.position_m[index] =
          make_estimate(centre.position_m(axis), nominal.position_m(axis) + u.position_m[index],
                        position(axis), priors.array_position_std_m, ratio);
    }
    const Eigen::VectorXd offsets = variances(u.mic_offsets_m.data(), static_cast<int>(3 * mics));
    const Eigen::VectorXd delays = variances(u.delays_s.data(), static_cast<int>(mics));
    for (std::size_t i = 0; i < mics; ++i) {
      std::array<Estimate, 3> mic;
      for (int axis = 0; axis < 3; ++axis) {
        const std::size_t k = 3 * i + static_cast<std::size_t>(axis);
        mic[static_cast<std::size_t>(axis)] =
            make_estimate(centre.mics_m[i](axis), nominal.mics_m[i](axis) + u.mic_offsets_m[k],
                          offsets(static_cast<Eigen::Index>(k)), nominal.mic_position_std_m, ratio);
      }
      out.mic_position_m.push_back(mic);
      const double applied_s =
          i < nominal.channel_delay_s.size() ? nominal.channel_delay_s[i] : 0.0;
      const double configured_s =
          i < centre.channel_delay_s.size() ? centre.channel_delay_s[i] : 0.0;
      out.channel_delay_s.push_back(make_estimate(
          configured_s, applied_s + u.delays_s[i], delays(static_cast<Eigen::Index>(i)),
          i == 0 ? 0.0 : priors.channel_delay_std_s, ratio));
    }
    out.clock_offset_s =
        make_estimate(centre.clock_offset_s, nominal.clock_offset_s + u.clock_s,
                      variances(&u.clock_s, 1)(0), priors.clock_offset_std_s, ratio);
    out.ground_echo_pull =
        make_estimate(0.0, u.ground_echo_pull, variances(&u.ground_echo_pull, 1)(0),
                      settings.bands_hz.empty() ? 0.0 : priors.ground_echo_pull_std, ratio);
    out.frames = 0;
    for (const auto& place : placed) out.frames += frames[place.frame].array == static_cast<int>(a);
    out.distinct_directions =
        distinct_directions(nominal, frames, placed, static_cast<int>(a), reference, positions,
                            settings.min_direction_separation_deg, 1000);
    out.before = before_per_array[a];
    out.after = stats_of(after, placed, frames, static_cast<int>(a));
    out.calibrated = nominal;
    out.calibrated.yaw_deg = out.yaw_deg.value;
    out.calibrated.pitch_deg = out.pitch_deg.value;
    out.calibrated.roll_deg = out.roll_deg.value;
    for (int axis = 0; axis < 3; ++axis)
      out.calibrated.position_m(axis) = out.position_m[static_cast<std::size_t>(axis)].value;
    for (std::size_t i = 0; i < mics; ++i) {
      for (int axis = 0; axis < 3; ++axis)
        out.calibrated.mics_m[i](axis) =
            out.mic_position_m[i][static_cast<std::size_t>(axis)].value;
    }
    result.arrays.push_back(std::move(out));
  }
  return result;
}

}  // namespace dronetrack::calib
