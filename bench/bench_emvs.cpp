// Throughput of the EMVS mapper: a keyframe of 2 M events at the full 346x260 resolution on the
// shipped number of planes and on 100, timed whole (pose slices, rays, the shared voting kernel
// and the depth extraction), with the extraction's share and the CPU time per
// event (all threads), and the depth extraction of such a DSI alone.
#include <benchmark/benchmark.h>

#include <chrono>
#include <ctime>
#include <limits>

#include "../test/common/synthetic_events.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/mapping/emvs.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/trajectory/ackermann_arc.h"

using namespace vwe_vo;

namespace {
const CameraModel& camera() {
  static const CameraModel cam(
      loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml"));
  return cam;
}

const AckermannArcModel& truth() {
  static const AckermannArcModel model(0.4, 0.6, 0, defaultTBaseCam());
  return model;
}

/// 2 M events of 3000 random points over 1 s (2 M distinct events, not a repeated packet).
const EventVector& events() {
  static const EventVector ev =
      synthetic::randomPointEvents(camera(), truth(), 2000000, 5, 0.5, 3000);
  return ev;
}

double cpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

EmvsOptions benchOptions(int threads, int planes = 0) {
  EmvsOptions o;
  o.volume.num_threads = threads;
  if (planes > 0) o.volume.num_planes = planes;
  o.max_event_rate_hz = 0.0;  // every event of the packet
  o.kf_distance_m = 100.0;    // one keyframe for the whole packet
  o.kf_rotation_deg = 180.0;
  o.max_events_per_keyframe = 10000000;
  return o;
}

const EmvsMapper::PoseFunction& truePose() {
  static const EmvsMapper::PoseFunction pose = [](int64_t t, Pose3* T) {
    *T = truth().T_Cr_Ct(t);
    return true;
  };
  return pose;
}

/// Buffered events -> keyframe through the incremental mapper, all of it timed: poses per slice
/// (process), then rays, votes and depth extraction (finish). the DSI alone is that minus
/// extract_s (the depth extraction timed again, untimed, on the same DSI); cpu_us_per_event is the
/// process CPU time of the keyframe per voted event, i.e. core-s per data-second at 1 Mev/s voted.
void BM_EmvsKeyframeDsiAndDepth(benchmark::State& state) {
  const int threads = int(state.range(0)), planes = int(state.range(1));
  const EmvsOptions o = benchOptions(threads, planes);
  EmvsMapper mapper(o, camera());
  size_t votes = 0, voted = 0;
  double extract_s = 0.0, cpu_s = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    mapper.addEvents(events());  // buffering only
    state.ResumeTiming();
    const double c0 = cpuSeconds();
    mapper.process(truePose(), std::numeric_limits<int64_t>::max());
    EmvsKeyframe kf;
    mapper.finish(&kf);
    cpu_s += cpuSeconds() - c0;
    state.PauseTiming();
    const auto t0 = std::chrono::steady_clock::now();
    EmvsKeyframe again;
    extractKeyframe(mapper.volume(), o, kf.T_odom_cam, &again);
    extract_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    state.ResumeTiming();
    votes += kf.counts.votes;
    voted += kf.counts.voted;
  }
  state.SetLabel("timed: process+finish = poses, rays, votes, depth extraction");
  state.counters["planes"] = double(o.volume.num_planes);
  state.counters["extract_s"] = extract_s / double(state.iterations());
  state.counters["cpu_us_per_event"] = voted ? 1e6 * cpu_s / double(voted) : 0.0;
  state.counters["s_per_keyframe"] = benchmark::Counter(
      double(state.iterations()), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["events_per_s"] = benchmark::Counter(double(voted), benchmark::Counter::kIsRate);
  state.counters["votes_per_s"] = benchmark::Counter(double(votes), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_EmvsKeyframeDsiAndDepth)
    ->ArgNames({"threads", "planes"})
    ->Args({1, 0})
    ->Args({2, 0})
    ->Args({1, 100})
    ->Args({2, 100})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(3);

/// Depth map + cloud of a full 2 M x 100 DSI (argmax, refinement, thresholds, median, outliers).
void BM_EmvsDepthExtraction(benchmark::State& state) {
  const EmvsOptions o = benchOptions(2);
  // The mapper's DSI (it keeps the votes of its last keyframe).
  EmvsMapper mapper(o, camera());
  mapper.addEvents(events());
  mapper.process(truePose(), std::numeric_limits<int64_t>::max());
  EmvsKeyframe first;
  mapper.finish(&first);
  size_t points = 0;
  for (auto _ : state) {
    EmvsKeyframe kf;
    extractKeyframe(mapper.volume(), o, Pose3::Identity(), &kf);
    points = kf.points_cam.size();
    benchmark::DoNotOptimize(kf.points_cam.data());
  }
  state.counters["points"] = double(points);
}
BENCHMARK(BM_EmvsDepthExtraction)->Unit(benchmark::kMillisecond)->UseRealTime();
}  // namespace

BENCHMARK_MAIN();
