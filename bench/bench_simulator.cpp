// Event simulator throughput: seconds of a standard sequence simulated per wall second.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <string>

#include "vwe_vo/io/config.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sim/sequences.h"

namespace {

using namespace vwe_vo;

void simulate(benchmark::State& state, const std::string& name, double seconds, int threads) {
  const sim::SequenceSpec spec = sim::findSequence(name);
  const CameraModel camera(
      loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml"));
  const auto trajectory = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  const sim::Scene scene = sim::buildScene(spec.scene, spec.seed, trajectory);
  sim::EventSimulatorOptions options = spec.simulator;
  options.num_threads = threads;
  size_t events = 0;
  double wall = 0;
  for (auto _ : state) {
    sim::EventSimulator simulator(scene, camera, spec.T_base_cam, trajectory, options);
    EventVector out;
    const auto t0 = std::chrono::steady_clock::now();
    for (int64_t t = 0; t < secToNs(seconds);) {
      t += 100000000;
      out.clear();
      simulator.simulateUntil(t, &out);
      events += out.size();
    }
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    benchmark::DoNotOptimize(out.data());
    state.counters["renders_per_sim_s"] = simulator.stats().renders / seconds;
    // Rendered tiles in units of full frames (tiles are re-rendered only when they need it).
    const double tiles = std::ceil(camera.width() / 16.0) * std::ceil(camera.height() / 16.0);
    state.counters["frames_per_sim_s"] = simulator.stats().tile_renders / tiles / seconds;
  }
  const double sim_s = seconds * state.iterations();
  state.counters["events_per_sim_s"] = events / sim_s;
  state.counters["events_per_wall_s"] = events / wall;
  state.counters["real_time_factor"] = wall / sim_s;
}

void BM_IndoorCircle2s(benchmark::State& state) {
  simulate(state, "indoor_circle", 2.0, static_cast<int>(state.range(0)));
}
BENCHMARK(BM_IndoorCircle2s)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->UseRealTime();

// The target: a 20 s indoor sequence (straights, 30 and 45 deg/s turns, stop-and-go,
// a 3 s standstill) at least 3x faster than real time on 2 threads (real_time_factor <= 0.33).
void BM_IndoorLong20s(benchmark::State& state) {
  simulate(state, "indoor_long", 20.0, 2);
}
BENCHMARK(BM_IndoorLong20s)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

void BM_StreetLong2s(benchmark::State& state) {
  simulate(state, "street_long", 2.0, 2);
}
BENCHMARK(BM_StreetLong2s)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
