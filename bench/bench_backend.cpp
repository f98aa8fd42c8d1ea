// Throughput of the back-end's multi-volume objective: evaluations (value + gradient w.r.t. the
// free control points) per second for 10 volumes x 20k events along a spline, on the default
// grid (half resolution, 30 planes, 2 threads); and of the IMU's parts (the gyro prior over a
// window, the attitude filter per sample), the cost the IMU adds to a refinement.
#include <benchmark/benchmark.h>

#include "../test/common/synthetic_events.h"
#include "vwe_vo/backend/backend.h"
#include "vwe_vo/backend/gyro_prior.h"
#include "vwe_vo/io/config.h"

using namespace vwe_vo;

namespace {
const CameraModel& camera() {
  static const CameraModel cam(
      loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml"));
  return cam;
}

/// A gentle curve at 0.4 m/s over 3 s as a spline (epoch 0).
std::shared_ptr<BSpline> curve() {
  std::vector<int64_t> t;
  std::vector<Vec2> p;
  for (double s = 0; s <= 3.0 + 1e-9; s += 0.01) {
    const double psi = 0.17 * s;
    t.push_back(secToNs(s));
    p.emplace_back(0.4 / 0.17 * std::sin(psi), 0.4 / 0.17 * (1 - std::cos(psi)));
  }
  BSplineFitOptions o;
  o.knot_spacing_s = 0.3;
  return std::make_shared<BSpline>(fitBSpline(t, p, o));
}

void BM_MultiVolumeObjective(benchmark::State& state) {
  const int num_volumes = int(state.range(0));
  const int events_per_volume = int(state.range(1));
  const bool with_gradient = state.range(2) != 0;
  VolumeOptions vo;  // the back-end's volume in config/vwe_vo.yaml
  vo.grid_scale = 1.0;
  vo.z_min_m = 0.8;
  vo.num_threads = int(state.range(3));
  VweObjectivePool vwe(camera(), vo);
  auto truth = curve();
  std::vector<BackendVolume> volumes;
  for (int i = 0; i < num_volumes; ++i) {
    const int64_t t_ref = secToNs(0.3 + 2.4 * (i + 0.5) / num_volumes);
    const BSplineCameraModel model(truth, defaultTBaseCam(), t_ref);
    volumes.push_back({t_ref, synthetic::randomPointEvents(camera(), model, events_per_volume,
                                                           i + 1, 0.2, 2000)});
  }
  auto spline = std::make_shared<BSpline>(*truth);
  MultiVolumeObjective objective(spline, defaultTBaseCam(), 4, volumes, &vwe);
  Eigen::VectorXd x = objective.freeParams();
  x.array() += 0.01;
  Eigen::VectorXd g;
  // Every evaluation at new parameters (the objective keeps its last results).
  const double x0 = x[0];
  int64_t k = 0;
  for (auto _ : state) {
    x[0] = x0 + 1e-12 * double(++k);
    benchmark::DoNotOptimize(objective.evaluate(x, with_gradient ? &g : nullptr));
  }
  if (objective.evaluations() < size_t(state.iterations()))
    state.SkipWithError("evaluations were served from kept results");
  state.counters["evals_per_s"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["events_per_s"] = benchmark::Counter(
      double(state.iterations()) * num_volumes * events_per_volume, benchmark::Counter::kIsRate);
  state.counters["free_params"] = double(objective.numFree());
}
BENCHMARK(BM_MultiVolumeObjective)
    ->ArgNames({"volumes", "events", "gradient", "threads"})
    ->Args({10, 20000, 1, 2})
    ->Args({10, 20000, 0, 2})
    ->Args({10, 4000, 1, 1})
    ->Args({10, 4000, 1, 2})
    ->Args({4, 8000, 1, 2})  // the shipped configs: 4 volumes of 8000 events per refinement
    ->Args({3, 8000, 1, 2})  // an odd count: the third volume on both threads
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The gyro prior of one refinement window (1.6 s in bins of 0.05 s), value + gradient.
void BM_GyroRatePrior(benchmark::State& state) {
  auto spline = curve();
  std::vector<GyroRatePrior::Bin> bins;
  for (double u = 1.2; u + 0.05 <= 2.8; u += 0.05) bins.push_back({u, u + 0.05, 0.17 + 0.003});
  const ImuFusionOptions o;
  const GyroRatePrior prior(spline, 4, bins, o.gyro_prior_weight,
                            o.gyro_noise_density_deg_s / kDegPerRad, 0.0, 0.01);
  Eigen::VectorXd g;
  for (auto _ : state) benchmark::DoNotOptimize(prior.evaluate(&g));
  state.counters["evals_per_s"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["bins"] = double(prior.numBins());
}
BENCHMARK(BM_GyroRatePrior)->Unit(benchmark::kMicrosecond);

// The attitude filter, per 1 kHz sample (real time needs 1000 per second).
void BM_AttitudeFilter(benchmark::State& state) {
  AttitudeFilter f(ImuFusionOptions(), Vec3(0.1, 0.0, 0.3));
  ImuSample s;
  s.gyro = Vec3(0.001, -0.002, 0.17);
  s.accel = Vec3(0.05, 0.07, 9.8);
  VehicleMotion m;
  m.v = 0.4, m.omega = 0.17;
  for (auto _ : state) {
    s.t_ns += 1000000;
    f.add(s, m);
    benchmark::DoNotOptimize(f.tilt());
  }
  state.counters["samples_per_s"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_AttitudeFilter);

}  // namespace

BENCHMARK_MAIN();
