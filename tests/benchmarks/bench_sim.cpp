// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-sim ray casting (issue #4 bar: one ~120k-point HDL-64E scan <= 100 ms on 2 threads),
// and one camera frame, on the default scenario.
// usage: cleanmap-bench-sim [google-benchmark flags]
#include <benchmark/benchmark.h>

#include "cleanmap/sim/world.h"

namespace {

void BM_SimulateScan(benchmark::State& state) {
  const auto sc = cleanmap::sim::defaultScenario();
  int k = 0;
  std::size_t points = 0;
  for (auto _ : state) {
    const auto s =
        cleanmap::sim::simulateScan(sc, k++ % sc.frames, static_cast<int>(state.range(0)));
    points += s.points.size();
    benchmark::DoNotOptimize(s.points.data());
  }
  state.counters["points/scan"] =
      static_cast<double>(points) / static_cast<double>(state.iterations());
}

void BM_SimulateScanSweepMotion(benchmark::State& state) {
  auto sc = cleanmap::sim::defaultScenario();
  sc.sensor.sweep_motion = true;
  int k = 0;
  for (auto _ : state) {
    const auto s =
        cleanmap::sim::simulateScan(sc, k++ % sc.frames, static_cast<int>(state.range(0)));
    benchmark::DoNotOptimize(s.points.data());
  }
}

void BM_RenderImage(benchmark::State& state) {
  const auto sc = cleanmap::sim::defaultScenario();
  const auto cam = cleanmap::sim::kittiCamera();
  int k = 0;
  for (auto _ : state) {
    const auto img =
        cleanmap::sim::renderImage(sc, k++ % sc.frames, cam, static_cast<int>(state.range(0)));
    benchmark::DoNotOptimize(img.data);
  }
}

}  // namespace

BENCHMARK(BM_SimulateScan)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(10)
    ->ReportAggregatesOnly(true);
BENCHMARK(BM_SimulateScanSweepMotion)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(10)
    ->ReportAggregatesOnly(true);
BENCHMARK(BM_RenderImage)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);
BENCHMARK_MAIN();
