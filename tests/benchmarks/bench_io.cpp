// SPDX-License-Identifier: BSD-3-Clause
// Reading one ~120k-point scan: from a KITTI .bin and from an MRPT rawlog (embedded points).
// usage: cleanmap-bench-io --data ../shared/data [google-benchmark flags]
#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>

#include "cleanmap/io/kitti.h"
#include "cleanmap/mrpt/rawlog.h"

namespace {

std::string g_set;  // a KITTI folder
std::string g_rawlog;

void BM_ReadKittiBin(benchmark::State& state) {
  const auto seq = cleanmap::io::KittiSequence::open(g_set);
  std::size_t i = 0, points = 0;
  for (auto _ : state) {
    const auto scan = cleanmap::io::readKittiBin(seq.scanPath(i++ % seq.size()));
    points += scan.size();
    benchmark::DoNotOptimize(scan.points.data());
  }
  state.counters["points/scan"] =
      static_cast<double>(points) / static_cast<double>(state.iterations());
}

void BM_ReadRawlogScan(benchmark::State& state) {
  std::unique_ptr<cleanmap::mrpt::RawlogSource> src;
  std::size_t points = 0;
  for (auto _ : state) {
    state.PauseTiming();
    if (!src) src = std::make_unique<cleanmap::mrpt::RawlogSource>(g_rawlog);
    state.ResumeTiming();
    auto f = src->next();
    if (!f) {  // wrapped around: reopen (not timed) and read
      state.PauseTiming();
      src = std::make_unique<cleanmap::mrpt::RawlogSource>(g_rawlog);
      state.ResumeTiming();
      f = src->next();
    }
    points += f->scan.size();
    benchmark::DoNotOptimize(f->scan.points.data());
  }
  state.counters["points/scan"] =
      static_cast<double>(points) / static_cast<double>(state.iterations());
}

}  // namespace

BENCHMARK(BM_ReadKittiBin)->Unit(benchmark::kMillisecond)->Repetitions(15)->ReportAggregatesOnly();
BENCHMARK(BM_ReadRawlogScan)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(15)
    ->ReportAggregatesOnly();

int main(int argc, char** argv) {
  std::string data = "../shared/data";
  std::vector<char*> rest = {argv[0]};
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--data") == 0 && i + 1 < argc)
      data = argv[++i];
    else
      rest.push_back(argv[i]);
  }
  g_set = data + "/kitti_highway";
  if (!std::filesystem::is_directory(g_set)) {
    std::cerr << "cleanmap-bench-io: " << g_set << ": not found (pass --data DIR)\n";
    return 1;
  }
  // The rawlog is made once from the same folder (not timed).
  g_rawlog = (std::filesystem::temp_directory_path() / "cleanmap-bench-io.rawlog").string();
  {
    const auto seq = cleanmap::io::KittiSequence::open(g_set);
    cleanmap::mrpt::RawlogWriter w(g_rawlog);
    for (std::size_t i = 0; i < seq.size(); ++i) {
      cleanmap::Frame f = seq.frame(i);
      f.image.reset();  // scans only: the benchmark is about points
      w.write(f, std::nullopt);
    }
    w.close();
  }
  int n = static_cast<int>(rest.size());
  benchmark::Initialize(&n, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  std::printf("peak RSS: %.1f MiB\n", static_cast<double>(ru.ru_maxrss) / 1024.0);
  std::filesystem::remove(g_rawlog);
  return 0;
}
