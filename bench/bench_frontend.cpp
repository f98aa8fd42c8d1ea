// Front-end real-time factor on simulated indoor_circle (3 s, generated once in process with the
// sequence's fixed seed): processing time of Frontend::addEvents/process over the data duration.
#include <benchmark/benchmark.h>

#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/sim/scene.h"
#include "vwe_vo/sim/sequences.h"

using namespace vwe_vo;

namespace {

struct Data {
  CameraModel camera;
  Pose3 T_base_cam;
  EventVector events;
  double duration_s;
};

const Data& data() {
  static const Data d = [] {
    const sim::SequenceSpec spec = sim::findSequence("indoor_circle");
    CameraModel camera(
        loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml"));
    const auto trajectory = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
    sim::EventSimulator simulator(sim::buildScene(spec.scene, spec.seed, trajectory), camera,
                                  spec.T_base_cam, trajectory, spec.simulator);
    EventVector events;
    simulator.simulateUntil(secToNs(3.0), &events);
    return Data{camera, spec.T_base_cam, std::move(events), 3.0};
  }();
  return d;
}

void BM_FrontendIndoorCircle(benchmark::State& state) {
  const Data& d = data();
  FrontendOptions options;
  options.nominal_speed_mps = 0.4;
  options.volume.num_threads = int(state.range(0));
  size_t windows = 0;
  for (auto _ : state) {
    Frontend frontend(options, d.camera, d.T_base_cam);
    for (size_t i = 0; i < d.events.size(); i += 50000) {
      frontend.addEvents(EventVector(d.events.begin() + i,
                                     d.events.begin() + std::min(d.events.size(), i + 50000)));
      windows += frontend.process().size();
    }
  }
  state.counters["real_time_factor"] =
      benchmark::Counter(double(state.iterations()) * d.duration_s,
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["windows_per_s"] =
      benchmark::Counter(double(windows), benchmark::Counter::kIsRate);
  state.counters["events_per_s"] =
      benchmark::Counter(double(d.events.size()) * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_FrontendIndoorCircle)
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
