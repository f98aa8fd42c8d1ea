// Throughput of the VWE: objective (+ gradient) evaluations per second and plane-votes per
// second for a 30k-event volume and the pipeline's window and volume sizes, on 1 and 2 threads; the
// DSI-sized voting workload of the mapper (2 M events x 100 planes at full 346x260 resolution); and
// the road's objective (one evaluation) and its per-window search (config/car.yaml's road).
#include <benchmark/benchmark.h>

#include <random>

#include "../test/common/synthetic_events.h"
#include "vwe_vo/frontend/ground_yaw.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/vwe/ground_objective.h"
#include "vwe_vo/vwe/ray_builder.h"
#include "vwe_vo/vwe/vwe_objective.h"

using namespace vwe_vo;

namespace {
const CameraModel& camera() {
  static const CameraModel cam(
      loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml"));
  return cam;
}

void BM_VweObjective(benchmark::State& state) {
  const int threads = int(state.range(0));
  const bool with_gradient = state.range(1) != 0;
  const int num_events = int(state.range(2));
  VolumeOptions vo;
  vo.num_threads = threads;
  vo.grid_scale = state.range(3) / 100.0;
  vo.z_min_m = 0.8;  // the front-end's and back-end's volume (config/vwe_vo.yaml)
  const auto& c = camera().calibration();
  ProjectiveVolume volume(vo, c.width, c.height, c.fx, c.fy, c.cx, c.cy);
  VweObjective objective(camera(), &volume);
  const AckermannArcModel truth(0.4, 0.4, secToNs(10.0), defaultTBaseCam());
  const EventVector events =
      synthetic::randomPointEvents(camera(), truth, num_events, 1, 0.15, 2000);
  AckermannArcModel model(0.38, 0.4, secToNs(10.0), defaultTBaseCam());
  Eigen::VectorXd g;
  size_t votes = 0;
  for (auto _ : state) {
    const VweEvaluation e = objective.evaluate(events, model, with_gradient ? &g : nullptr);
    votes += e.votes;
    benchmark::DoNotOptimize(e.contrast);
  }
  state.counters["evals_per_s"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["plane_votes_per_s"] =
      benchmark::Counter(double(votes), benchmark::Counter::kIsRate);
  state.counters["plane_votes_per_s_per_thread"] =
      benchmark::Counter(double(votes) / threads, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_VweObjective)
    ->ArgNames({"threads", "gradient", "events", "scale_pct"})
    ->Args({1, 0, 30000, 50})
    ->Args({2, 0, 30000, 50})
    ->Args({2, 1, 30000, 50})
    ->Args({1, 0, 8000, 100})  // a front-end window of config/vwe_vo.yaml
    ->Args({2, 0, 8000, 100})
    ->Args({2, 1, 4000, 100})  // a back-end volume
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

/// Pure voting of precomputed rays: the kernel the VWE and the EMVS DSI share.
void BM_VotingKernel(benchmark::State& state) {
  const int threads = int(state.range(0));
  const int num_events = int(state.range(1));
  const int planes = int(state.range(2));
  const double scale = state.range(3) / 100.0;
  VolumeOptions vo;
  vo.num_threads = threads;
  vo.num_planes = planes;
  vo.grid_scale = scale;
  vo.margin_px = 0;
  const auto& c = camera().calibration();
  ProjectiveVolume volume(vo, c.width, c.height, c.fx, c.fy, c.cx, c.cy);
  const AckermannArcModel truth(0.4, 0.4, 0, defaultTBaseCam());
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 30000, 2, 0.5, 3000);
  std::vector<VolumeRay> rays;
  rays.reserve(num_events);
  const VolumeRayBuilder<double> make_ray(volume);
  for (int i = 0; i < num_events; ++i) {
    const PixelEvent& e = events[i % events.size()];
    const Pose3 T = truth.T_Cr_Ct(e.t_ns);
    VolumeRay r;
    if (make_ray(RayPose<double>(T.linear(), T.translation()),
                 camera().bearing(e.x, e.y).cast<double>(), &r))
      rays.push_back(r);
  }
  size_t votes = 0;
  for (auto _ : state) {
    votes += volume.vote(rays);
    benchmark::DoNotOptimize(volume.sum());
    volume.clear(rays);
  }
  state.counters["plane_votes_per_s"] =
      benchmark::Counter(double(votes), benchmark::Counter::kIsRate);
  state.counters["plane_votes_per_s_per_thread"] =
      benchmark::Counter(double(votes) / threads, benchmark::Counter::kIsRate);
  state.counters["events_per_s"] =
      benchmark::Counter(double(rays.size()) * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_VotingKernel)
    ->ArgNames({"threads", "events", "planes", "scale_pct"})
    ->Args({1, 30000, 30, 50})
    ->Args({2, 30000, 30, 50})
    ->Args({1, 8000, 30, 100})  // sparse votes: a front-end window
    ->Args({2, 8000, 30, 100})
    ->Args({1, 2000000, 100, 100})
    ->Args({2, 2000000, 100, 100})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
/// Road events of a car (config/car.yaml's mount) turning at 8 deg/s at 7 m/s with its body
/// pitching: random texture on the road 3-9 m ahead, n events over a 0.3 s window.
EventVector carRoadEvents(const PitchedArcModel& truth, const Pose3& T_base_cam, int n) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> ux(3.0, 9.0), uy(-4.0, 4.0);
  const Pose3 T_cam_base = T_base_cam.inverse();  // the body is level at t_ref (pitch 0 there)
  std::vector<Vec3> points;
  for (int i = 0; i < 3000; ++i) points.push_back(T_cam_base * Vec3(ux(rng), uy(rng), 0.0));
  return synthetic::pointEvents(camera(), truth, points, n, &rng, 0.15);
}

Pose3 carMount() {
  return mountToTBaseCam(Vec3(1.5, 0, 1.4), 0, 5 / kDegPerRad, 0);
}

/// One evaluation of the road's objective (frontend.ground: a vote per event, no planes).
void BM_GroundObjective(benchmark::State& state) {
  const int64_t t_ref = secToNs(10.0);
  const PitchedArcModel truth(8 / kDegPerRad, 7.0, t_ref, carMount(), 0.0, 1 / kDegPerRad);
  const EventVector events = carRoadEvents(truth, carMount(), int(state.range(0)));
  GroundObjective objective(GroundObjectiveOptions(), camera(), carMount());
  const PitchedArcModel model(7.5 / kDegPerRad, 7.0, t_ref, carMount(), 0.1 / kDegPerRad, 0.0);
  const GroundEvents prepared = objective.prepare(events, model);
  const GroundPlane plane = model.groundInReference();
  for (auto _ : state) benchmark::DoNotOptimize(objective.evaluate(prepared, model, plane));
  state.counters["events_per_s"] =
      benchmark::Counter(double(prepared.size()) * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_GroundObjective)
    ->ArgNames({"events"})
    ->Arg(10000)  // config/car.yaml's frontend.ground.max_events
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

/// The road's whole search of one window (GroundYaw::estimate: ~80 evaluations), on 2 threads.
void BM_GroundYawWindow(benchmark::State& state) {
  const int64_t t_ref = secToNs(10.0);
  const PitchedArcModel truth(8 / kDegPerRad, 7.0, t_ref, carMount(), 0.0, 1 / kDegPerRad);
  const EventVector events = carRoadEvents(truth, carMount(), 40000);
  GroundYawOptions o;
  o.weight = 0.5;
  o.num_threads = 2;
  GroundYaw ground(o, camera(), carMount());
  const int64_t t0 = t_ref - secToNs(0.15), t1 = t_ref + secToNs(0.15);
  int evaluations = 0;
  for (auto _ : state) {
    const GroundYawEstimate e = ground.estimate(events, t0, t1, t_ref, 7.0, 0.0, 7 / kDegPerRad, 1);
    evaluations += e.evaluations;
    benchmark::DoNotOptimize(e.omega);
  }
  state.counters["evaluations_per_window"] = double(evaluations) / double(state.iterations());
}
BENCHMARK(BM_GroundYawWindow)->Unit(benchmark::kMillisecond)->UseRealTime();
}  // namespace

BENCHMARK_MAIN();
