// UKF (and alternatives) measurement updates per second on one core, and the FusionEngine's DOA
// throughput with four arrays and one drone. items_per_second is the figure to read.
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "fusion/fusion_engine.hpp"
#include "fusion/outlier_share.hpp"
#include "fusion/track_filter.hpp"

namespace dronetrack::fusion {
namespace {

// The DOA likelihood by a benchmark argument: 0 gaussian, 1 outlier_mixture, 2 student_t,
// 3 outlier_mixture with e estimated from the gated DOAs as the engine does per array
// (outlier_share.hpp, adaptive_outlier_probability) (doa_likelihood.hpp, the engine's defaults
// otherwise).
DoaLikelihoodKind likelihood_of(std::int64_t argument) {
  return argument == 1 || argument == 3 ? DoaLikelihoodKind::outlier_mixture
         : argument == 2                ? DoaLikelihoodKind::student_t
                                        : DoaLikelihoodKind::gaussian;
}

// One asynchronous DOA step: predict 50 ms, innovation from one of three arrays, update.
// imm: 0 single model, 1 the IMM over three jerk levels, 2 the same plus three
// coordinated-turn modes. likelihood: likelihood_of; outliers: every 4th DOA is ~3 degrees off.
void filter_update(benchmark::State& state, FilterKind kind, int imm = 0,
                   std::int64_t likelihood = 0, bool outliers = false) {
  FilterSettings settings;
  const FusionParams defaults;
  settings.likelihood = DoaLikelihood(likelihood_of(likelihood), defaults.student_t_dof,
                                      defaults.outlier_probability, defaults.gate_probability);
  settings.motion.jerk_variance_m2ps6 = 9.0;
  settings.particle_count = 1000;
  if (imm >= 1) settings.imm_jerk_std_mps3 = {0.2, 3.0, 30.0};
  if (imm >= 2) settings.imm_turn_rate_std_radps2 = {0.5, 3.0, 20.0};
  auto filter = make_track_filter(kind, settings);
  StateVector mean = StateVector::Zero();
  mean.segment<3>(StateBlock::position) << 40, 60, 30;
  mean.segment<3>(StateBlock::velocity) << 5, -2, 0;
  StateCovariance covariance = StateCovariance::Identity();
  filter->initialise(mean, covariance);
  const DoaMeasurementModel models[3] = {
      {{0, 0, 1.5}, 343.0, 3}, {{100, 0, 1.5}, 343.0, 3}, {{50, 90, 1.5}, 343.0, 3}};
  const MeasurementCovariance noise = MeasurementCovariance::Identity() * 7.6e-5;
  StateVector truth = mean;
  std::mt19937_64 random(1);
  std::normal_distribution<double> normal(0.0, 0.0087);
  std::size_t step = 0;
  Innovation innovation;
  OutlierShareEstimate share(defaults.outlier_probability, defaults.outlier_prior_doas,
                             defaults.outlier_window_doas);
  for (auto _ : state) {
    truth = ConstantJerkModel::propagate(truth, 0.05);
    filter->predict(0.05);
    const DoaMeasurementModel& model = models[step++ % 3];
    const double spread = outliers && step % 4 == 0 ? 6.0 : 1.0;
    const Measurement z =
        model.predict(truth) + spread * Measurement(normal(random), normal(random));
    filter->innovation(model, noise, innovation);
    if (likelihood == 3) {
      innovation.outlier_probability = share.share();
      const double d2 = innovation.mahalanobis2(z);
      if (d2 <= settings.likelihood.gate_d2()) {
        share.add(settings.likelihood.outlier_density_ratio(d2, 2));
        share.refresh();
      }
    }
    benchmark::DoNotOptimize(filter->update(innovation, z));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}

// Arguments: likelihood (likelihood_of), outliers (0 or 1).
void BM_UkfUpdate(benchmark::State& state) {
  filter_update(state, FilterKind::ukf, 0, state.range(0), state.range(1) != 0);
}
void BM_UkfSeed002Update(benchmark::State& state) { filter_update(state, FilterKind::ukf_seed002); }
void BM_EkfUpdate(benchmark::State& state) { filter_update(state, FilterKind::ekf); }
void BM_ParticleUpdate(benchmark::State& state) { filter_update(state, FilterKind::particle); }
void BM_ImmUkfUpdate(benchmark::State& state) { filter_update(state, FilterKind::ukf, 1); }
void BM_ImmTurnUkfUpdate(benchmark::State& state) { filter_update(state, FilterKind::ukf, 2); }
BENCHMARK(BM_UkfUpdate)->ArgNames({"likelihood", "outliers"})->ArgsProduct({{0, 1, 2, 3}, {0, 1}});
BENCHMARK(BM_ImmUkfUpdate);
BENCHMARK(BM_ImmTurnUkfUpdate);
BENCHMARK(BM_UkfSeed002Update);
BENCHMARK(BM_EkfUpdate);
BENCHMARK(BM_ParticleUpdate);

doa::ArrayGeometry tetrahedron(const char* id, Eigen::Vector3d position) {
  doa::ArrayGeometry array;
  array.id = id;
  array.position_m = position;
  array.mics_m = {
      {0, 0, 0.5}, {0.4714, 0, -0.1667}, {-0.2357, 0.4082, -0.1667}, {-0.2357, -0.4082, -0.1667}};
  return array;
}

// Whole engine: four arrays each reporting one drone every 50 ms (80 DOAs/s of scene time).
// Arguments: imm_turn_mode off (0) or on (1); likelihood (likelihood_of); every 4th DOA an
// outlier of ~3 degrees (1) or none (0); the rest default.
void BM_EngineFourArrays(benchmark::State& state) {
  FusionParams params;
  params.imm_turn_mode = state.range(0) != 0;
  params.likelihood = likelihood_of(state.range(1));
  params.adaptive_outlier_probability = state.range(1) == 3;
  const bool outliers = state.range(2) != 0;
  const std::vector<doa::ArrayGeometry> arrays{
      tetrahedron("N1", {-100, -100, 2}), tetrahedron("N2", {100, -100, 2}),
      tetrahedron("N3", {100, 100, 2}), tetrahedron("N4", {-100, 100, 2})};
  std::vector<doa::DoaMeasurement> doas;
  std::mt19937_64 random(2);
  std::normal_distribution<double> noise(0.0, 0.0087);
  for (int step = 0; step < 1200; ++step) {  // 60 s
    const double t = step * 0.05;
    const Eigen::Vector3d drone(-150 + 5 * t, 10 + 20 * std::sin(0.1 * t), 35);
    for (std::size_t a = 0; a < arrays.size(); ++a) {
      const Eigen::Vector3d d = (drone - arrays[a].centre_site_m()).normalized();
      doa::DoaMeasurement m;
      m.array_id = arrays[a].id;
      m.array_index = static_cast<int>(a);
      m.time_s = t;
      const double spread = outliers && (step + a) % 4 == 0 ? 6.0 : 1.0;
      m.direction =
          (d + spread * Eigen::Vector3d(noise(random), noise(random), noise(random))).normalized();
      m.azel_covariance_rad2 = Eigen::Matrix2d::Identity() * 7.6e-5;
      doas.push_back(m);
    }
  }
  std::vector<TrackReport> tracks;
  for (auto _ : state) {
    FusionEngine engine(params, arrays, 343.0);
    for (const auto& m : doas) {
      engine.add(m);
      engine.advance_to(m.time_s);
    }
    engine.tracks_at(60.0, tracks);
    benchmark::DoNotOptimize(tracks.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * doas.size()));
}
BENCHMARK(BM_EngineFourArrays)
    ->Args({0, 0, 0})
    ->Args({1, 0, 0})
    ->Args({1, 1, 0})
    ->Args({1, 2, 0})
    ->Args({1, 0, 1})
    ->Args({1, 1, 1})
    ->Args({1, 2, 1})
    ->Args({1, 3, 0})
    ->Args({1, 3, 1})
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace dronetrack::fusion
BENCHMARK_MAIN();
