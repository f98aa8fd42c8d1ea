// Throughput of the EMVS mapper: a keyframe of 2 M events x 100 planes at the full 346x260
// resolution (pose slices, rays, the shared voting kernel and the depth extraction; target
// <= 0.7 s for the DSI on 2 threads) and the depth extraction of such a DSI alone.
#include <benchmark/benchmark.h>

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

EmvsOptions benchOptions(int threads) {
  EmvsOptions o;
  o.volume.num_threads = threads;
  o.kf_distance_m = 100.0;  // one keyframe for the whole packet
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
/// (process), then rays, votes and depth extraction (finish). The DSI alone is this minus
/// BM_EmvsDepthExtraction.
void BM_EmvsKeyframeDsiAndDepth(benchmark::State& state) {
  const int threads = int(state.range(0));
  EmvsMapper mapper(benchOptions(threads), camera());
  size_t votes = 0, voted = 0;
  for (auto _ : state) {
    state.PauseTiming();
    mapper.addEvents(events());  // buffering only
    state.ResumeTiming();
    mapper.process(truePose(), std::numeric_limits<int64_t>::max());
    EmvsKeyframe kf;
    mapper.finish(&kf);
    votes += kf.counts.votes;
    voted += kf.counts.voted;
  }
  state.SetLabel("process+finish: poses, rays, votes, depth extraction");
  state.counters["s_per_keyframe"] = benchmark::Counter(
      double(state.iterations()), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["events_per_s"] = benchmark::Counter(double(voted), benchmark::Counter::kIsRate);
  state.counters["votes_per_s"] = benchmark::Counter(double(votes), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_EmvsKeyframeDsiAndDepth)
    ->ArgNames({"threads"})
    ->Arg(1)
    ->Arg(2)
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
