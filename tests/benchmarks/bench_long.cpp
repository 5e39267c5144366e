// SPDX-License-Identifier: BSD-3-Clause
// Issue #15, long runs: a long simulated drive through the laser pipeline (default parameters,
// free-space cleaning on), printing per block of scans the resident memory and the time per scan.
// The default street (datasets/scenarios/default.ini) is driven back and forth, and so are its
// movers, so the scene stays busy and the area bounded: memory must stay flat whatever the
// number of scans. Outputs are not written (the app streams them to disk, doc/BENCHMARK.md).
// The lidar is simulated ahead of each scan and not timed.
//
// usage: cleanmap-bench-long [--scans N] [--every M] [--threads T] [--rings 64|32|16] [--epoch E]
//   one line per M scans: scans, RSS and peak RSS (MiB), median / p90 / max ms per scan
//   (LaserPipeline::push) over the block, the process CPU time per scan over the block (ms, all
//   threads, the simulator's excluded: less sensitive than wall time to a neighbour's load), and
//   the free-space map's memory (MiB).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <string>
#include <vector>

#include "cleanmap/core/error.h"
#include "cleanmap/core/median.h"
#include "cleanmap/core/sensor.h"
#include "cleanmap/pipeline/laser_pipeline.h"
#include "cleanmap/sim/world.h"

namespace {

// VmRSS / VmHWM of this process, MiB.
double procStatusMiB(const char* key) {
  std::ifstream f("/proc/self/status");
  std::string k;
  double kb = 0;
  while (f >> k) {
    if (k == key) {
      f >> kb;
      return kb / 1024.0;
    }
    f.ignore(1 << 12, '\n');
  }
  return 0;
}

double cpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

// A polyline driving `path` forwards and backwards `legs` times.
std::vector<Eigen::Vector2d> shuttle(const std::vector<Eigen::Vector2d>& path, int legs) {
  std::vector<Eigen::Vector2d> out = path;
  for (int l = 1; l < legs; ++l)
    for (std::size_t i = 1; i < path.size(); ++i)
      out.push_back(l % 2 ? path[path.size() - 1 - i] : path[i]);
  return out;
}

int usage() {
  std::fprintf(stderr,
               "usage: cleanmap-bench-long [--scans N] [--every M] [--threads T] "
               "[--rings 64|32|16] [--epoch E]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace cleanmap;
  int scans = 10000, every = 500, threads = 2, rings = 64, epoch = PipelineParams{}.epoch;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return usage();
    const int v = std::atoi(argv[++i]);
    if (a == "--epoch" && v >= 0) {  // 0: one epoch (DESIGN §2f)
      epoch = v;
      continue;
    }
    if (v <= 0) return usage();
    if (a == "--scans")
      scans = v;
    else if (a == "--every")
      every = v;
    else if (a == "--threads")
      threads = v;
    else if (a == "--rings" && (v == 64 || v == 32 || v == 16))
      rings = v;
    else
      return usage();
  }
  try {
    sim::Scenario sc = sim::defaultScenario();
    sc.frames = scans;
    sc.sensor.camera = false;
    if (rings != 64) {
      const SensorModel m = rings == 32 ? SensorModel::kHdl32 : SensorModel::kVlp16;
      sc.sensor.elevations = ringElevations(m);
      sc.sensor.azimuth_step_deg = sensorPreset(m).azimuth_step_deg;
    }
    // 100 m of street per leg at the scenario's speed; enough legs for every scan.
    const double leg_s = 100.0 / sc.ego_speed;
    const int legs = static_cast<int>(scans / (leg_s * sc.rate_hz)) + 2;
    sc.ego_path = shuttle({{-10, -2.5}, {90, -2.5}}, legs);
    for (auto& mv : sc.movers) mv.path = shuttle(mv.path, 4 * legs);

    PipelineParams params;
    params.threads = threads;
    params.epoch = epoch;
    std::size_t decided = 0;
    LaserPipeline pipe(params, [&](ScanResult&&) { ++decided; });
    std::printf(
        "# cleanmap-bench-long: %d scans of the default street driven back and forth, "
        "%d rings, %d threads, run.epoch %d, default parameters otherwise\n",
        scans, rings, threads, epoch);
    std::printf("%8s %9s %9s %8s %8s %8s %8s %9s\n", "scans", "rss_mib", "peak_mib", "med_ms",
                "p90_ms", "max_ms", "cpu_ms", "free_mib");
    std::vector<double> block;
    double cpu = 0;
    for (int k = 0; k < scans; ++k) {
      Frame f = sim::frameOf(sim::simulateScan(sc, k, threads), k);
      const double c0 = cpuMs();
      const auto t0 = std::chrono::steady_clock::now();
      pipe.push(std::move(f));
      cpu += cpuMs() - c0;
      block.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      if (static_cast<int>(block.size()) == every || k + 1 == scans) {
        std::sort(block.begin(), block.end());
        const auto* fs = pipe.freeSpace();
        std::printf("%8d %9.1f %9.1f %8.1f %8.1f %8.1f %8.1f %9.1f\n", k + 1,
                    procStatusMiB("VmRSS:"), procStatusMiB("VmHWM:"), median(block),
                    block[block.size() * 9 / 10], block.back(), cpu / double(block.size()),
                    fs ? static_cast<double>(fs->bytes()) / (1 << 20) : 0.0);
        std::fflush(stdout);
        block.clear();
        cpu = 0;
      }
    }
    pipe.finish();
    std::printf("# decided %zu scans\n", decided);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cleanmap-bench-long: %s\n", e.what());
    return 1;
  }
}
