// Reading Event Camera Dataset text: M events/s of EcdEventReader on a synthetic events.txt and
// events.txt.gz (2 M events at the DAVIS346's size, stamps near the Unix epoch as in the
// dataset), streamed in the offline runner's chunks, on one thread.
#include <benchmark/benchmark.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>

#include "vwe_vo/io/trajectory_io.h"

using namespace vwe_vo;

namespace {

constexpr size_t kEvents = 2000000;

std::string g_paths[2];

/// Writes the synthetic file once per process (plain or gzip); returns its path.
const std::string& eventsFile(bool gz) {
  std::string& path = g_paths[gz ? 1 : 0];
  if (!path.empty()) return path;
  const char* tmp = std::getenv("TMPDIR");
  path = std::string(tmp ? tmp : "/tmp") + "/vwe_vo_bench_io_" + std::to_string(::getpid()) +
         (gz ? "_events.txt.gz" : "_events.txt");
  EventVector events(kEvents);
  std::mt19937 rng(1);
  int64_t t = 1403636580LL * kNsPerSec;
  for (PixelEvent& e : events) {
    t += rng() % 2000;  // ~1 M events/s
    e.t_ns = t;
    e.x = static_cast<uint16_t>(rng() % 346);
    e.y = static_cast<uint16_t>(rng() % 260);
    e.polarity = rng() % 2 ? 1 : -1;
  }
  EcdEventWriter(path).write(events);
  return path;
}

void removeFiles() {
  for (const std::string& path : g_paths)
    if (!path.empty()) std::remove(path.c_str());
}

void BM_EcdRead(benchmark::State& state) {
  const bool gz = state.range(0) != 0;
  const std::string& path = eventsFile(gz);
  struct stat st {};
  stat(path.c_str(), &st);
  size_t events = 0;
  for (auto _ : state) {
    EcdEventReader reader(path, 346, 260);
    EventVector chunk;
    while (reader.read(50000, &chunk) > 0) events += chunk.size();  // vwe_vo_offline's chunks
  }
  if (events != kEvents * state.iterations()) state.SkipWithError("event count mismatch");
  state.counters["M_events_per_s"] =
      benchmark::Counter(double(events) * 1e-6, benchmark::Counter::kIsRate);
  state.counters["MB_per_s"] = benchmark::Counter(
      double(st.st_size) * 1e-6 * double(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["file_MB"] = double(st.st_size) * 1e-6;
  state.counters["events"] = double(kEvents);
}
BENCHMARK(BM_EcdRead)
    ->ArgNames({"gzip"})
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);  // rates per CPU second of the reading thread (the machine may be shared)

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  removeFiles();
  return 0;
}
