// SPDX-License-Identifier: BSD-3-Clause
// Issue #16: one benchmark per laser stage on fixed inputs, one thread: 21 scans of
// kitti_highway with their given poses (--data DIR, default ../shared/data), or 21 scans of the
// default simulated street where that set is absent. Scan 10 is the scan being decided, the
// others its window; every 6th point of scan 10 above the road is tested, in the pipeline's order
// (MovingTest::testOrder; CLEANMAP_BENCH_SCAN_ORDER=1: the scan's). `BM_MovingTest/0` is the fast
// beam maths, `/1` the libm reference path (BeamMath): their ratio is the vectorised masses' gain;
// `/2` the fast maths with the pose error of estimated poses (`--poses gicp`: the scan-conflict
// check's widened cone, issue #11); `/3` the fast maths with the empty runs (DESIGN §2b), as the
// pipeline tests: `/0` and `/1` are the votes alone.
// usage: cleanmap-bench-stages [--data DIR] [google-benchmark flags]
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

#include "cleanmap/core/beam_index.h"
#include "cleanmap/core/duplicate_filter.h"
#include "cleanmap/core/free_space.h"
#include "cleanmap/core/grazing.h"
#include "cleanmap/core/ground.h"
#include "cleanmap/core/moving_test.h"
#include "cleanmap/core/object_consensus.h"
#include "cleanmap/core/params.h"
#include "cleanmap/core/sensor.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/registration/odometry.h"
#include "cleanmap/sim/world.h"

namespace {

using namespace cleanmap;

std::string g_data = "../shared/data";

struct Inputs {
  std::string name;
  std::vector<Scan> scans;  // sensor frame, pose set
  std::size_t center = 10;
  std::vector<BeamIndex> beams;
  std::vector<WindowScan> window;
  std::vector<WindowScan> window_estimated;  // with the pose error of estimated poses (issue #11)
  std::vector<Eigen::Vector3d> tested;       // every 6th point of the center scan above the road
  std::vector<uint8_t> member;               // the center scan's points within 50 m, above the road
};

const Inputs& inputs() {
  static const Inputs in = [] {
    Inputs r;
    const std::string set = g_data + "/kitti_highway";
    if (std::filesystem::is_directory(set)) {
      const auto seq = io::KittiSequence::open(set);
      for (std::size_t i = 0; i <= 20; ++i) r.scans.push_back(seq.loadScan(i));
      r.name = set;
    } else {
      const auto sc = sim::defaultScenario();
      for (int k = 0; k <= 20; ++k)
        r.scans.push_back(sim::frameOf(sim::simulateScan(sc, k), k).scan);
      r.name = "simulated default street (" + set + " not found)";
    }
    const DsParams ds;
    const double radius = ds.search_lambdas * ds.lambda_theta;
    for (const auto& s : r.scans) r.beams.emplace_back(s.points, radius);
    for (std::size_t i = 0; i < r.scans.size(); ++i)
      if (i != r.center)
        r.window.push_back({&r.beams[i], r.scans[i].pose.inverse(), 0.0, 0.0,
                            static_cast<int>(i) - static_cast<int>(r.center)});
    // As the pipeline's window with gicp poses: relative_error times the path between the scans.
    const double e = RegistrationParams{}.relative_error;
    for (std::size_t i = 0; i < r.scans.size(); ++i) {
      if (i == r.center) continue;
      double path = 0;
      for (std::size_t a = std::min(i, r.center); a < std::max(i, r.center); ++a)
        path += (r.scans[a + 1].pose.translation() - r.scans[a].pose.translation()).norm();
      r.window_estimated.push_back({&r.beams[i], r.scans[i].pose.inverse(), (e * path) * (e * path),
                                    0.0, static_cast<int>(i) - static_cast<int>(r.center)});
    }
    const auto& c = r.scans[r.center];
    std::vector<Eigen::Vector3f> tested;  // sensor frame
    for (std::size_t j = 0; j < c.points.size(); ++j) {
      const auto& p = c.points[j];
      const bool above = p.z > -1.4f && std::abs(p.x) <= 50 && std::abs(p.y) <= 50;
      r.member.push_back(above);
      if (above && j % 6 == 0) tested.push_back(p.xyz());
    }
    // In the order the pipeline tests them (std::getenv("CLEANMAP_BENCH_SCAN_ORDER"): the scan's).
    std::vector<uint32_t> order(tested.size());
    for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
    if (!std::getenv("CLEANMAP_BENCH_SCAN_ORDER")) order = MovingTest(ds).testOrder(tested);
    for (const uint32_t i : order) r.tested.push_back(c.pose * tested[i].cast<double>());
    std::cerr << "stages: " << r.name << ", " << r.scans.size() << " scans, "
              << r.scans[r.center].points.size() << " points in scan " << r.center << ", "
              << r.tested.size() << " tested\n";
    return r;
  }();
  return in;
}

void BM_BeamIndex(benchmark::State& state) {
  const auto& in = inputs();
  const DsParams ds;
  for (auto _ : state) {
    const BeamIndex idx(in.scans[in.center].points, ds.search_lambdas * ds.lambda_theta);
    benchmark::DoNotOptimize(idx.size());
  }
}

// DESIGN §2b, §2e: the stretches of the scan's beams that graze a flat surface (with the
// azimuths the pipeline computes for them), once per scan beside the beam index.
void BM_Grazing(benchmark::State& state) {
  const auto& in = inputs();
  const MapParams m;
  const Scan& s = in.scans[in.center];
  GrazingStretches g;
  std::vector<float> azimuth(s.points.size());
  for (auto _ : state) {
    for (std::size_t n = 0; n < s.points.size(); ++n)
      azimuth[n] = fast::atan2(s.points[n].y, s.points[n].x);
    g.compute(s.points, s.pose.linear().cast<float>(), azimuth, m.flat_slope, m.margin,
              m.graze_reach);
    benchmark::DoNotOptimize(g.from().data());
  }
}

void BM_MovingTest(benchmark::State& state) {
  const auto& in = inputs();
  const MovingTest t(DsParams{}, state.range(0) == 1 ? BeamMath::kReference : BeamMath::kFast);
  const auto& window = state.range(0) == 2 ? in.window_estimated : in.window;
  const bool runs = state.range(0) == 3;
  MovingTestStats st;
  std::size_t moving = 0;
  for (auto _ : state)
    for (const auto& p : in.tested) moving += t.isMoving(p, window, &st, 0, runs);
  const double n = static_cast<double>(state.iterations());
  state.counters["tested"] = static_cast<double>(in.tested.size());
  state.counters["moving"] = static_cast<double>(moving) / n;
  state.counters["visits/pt"] = static_cast<double>(st.scans_visited) / (n * in.tested.size());
  state.counters["beams/visit"] = static_cast<double>(st.beams) /
                                  static_cast<double>(std::max<std::size_t>(st.scans_visited, 1));
}

void BM_Ground(benchmark::State& state) {
  const auto& in = inputs();
  for (auto _ : state) {
    const auto g = segmentGround(in.scans[in.center].points, GroundParams{}, 50.0, -1.73);
    benchmark::DoNotOptimize(g.data());
  }
}

// The per-scan sensor checks of the crop + ground stage (issue #15): the ground height under the
// sensor and the angular resolution, measured from the scan.
void BM_SensorChecks(benchmark::State& state) {
  const auto& pts = inputs().scans[inputs().center].points;
  for (auto _ : state) {
    benchmark::DoNotOptimize(estimateGroundHeight(pts));
    benchmark::DoNotOptimize(measureResolution(pts));
  }
}

// Issue #11's speed bar: GICP odometry alone (no pipeline beside it), the 21 scans tracked from
// the first, default parameters, state.range(0) threads. "s/scan" is the mean per scan.
void BM_Registration(benchmark::State& state) {
  const auto& in = inputs();
  for (auto _ : state) {
    reg::Odometry odo(RegistrationParams{}, static_cast<int>(state.range(0)));
    for (std::size_t i = 0; i < in.scans.size(); ++i)
      benchmark::DoNotOptimize(
          odo.track(in.scans[i].points, 0.1 * double(i), static_cast<int64_t>(i)).accepted);
  }
  state.counters["s/scan"] = benchmark::Counter(
      static_cast<double>(in.scans.size()),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void BM_DuplicateFilter(benchmark::State& state) {
  // The filter as the pipeline fills it: each of the scans before the center adds its points
  // above the road that are not duplicates of the scans before it (the compact static map);
  // then one query per point of the center scan above the road.
  const auto& in = inputs();
  DuplicateFilter f{FilterParams{}};
  for (std::size_t i = 0; i < in.center; ++i) {
    std::vector<Eigen::Vector3f> pts;
    for (const auto& p : in.scans[i].points) {
      if (!(p.z > -1.4f)) continue;
      const Eigen::Vector3f w = (in.scans[i].pose * p.xyz().cast<double>()).cast<float>();
      if (!f.isDuplicate(w, static_cast<long>(i))) pts.push_back(w);
    }
    f.insert(pts, static_cast<long>(i));
  }
  state.counters["entries"] = static_cast<double>(f.size());
  std::vector<Eigen::Vector3f> q;
  const auto& c = in.scans[in.center];
  for (std::size_t j = 0; j < c.points.size(); ++j)
    if (in.member[j]) q.push_back((c.pose * c.points[j].xyz().cast<double>()).cast<float>());
  std::size_t dup = 0;
  for (auto _ : state)
    for (const auto& p : q) dup += f.isDuplicate(p, static_cast<long>(in.center));
  state.counters["queries"] = static_cast<double>(q.size());
  state.counters["duplicates"] = static_cast<double>(dup) / static_cast<double>(state.iterations());
}

void BM_ObjectConsensus(benchmark::State& state) {
  // Every 20th member point called moving: groups are formed and judged as in the pipeline.
  const auto& in = inputs();
  const auto& c = in.scans[in.center];
  std::vector<uint8_t> seed(c.points.size(), 0);
  for (std::size_t j = 0; j < seed.size(); j += 20) seed[j] = in.member[j];
  ConsensusRules rules;  // the pipeline's: a dense lidar's, low surfaces split (OBJECTS.md rule 1)
  rules.reach = ringReach(ObjectParams{}, 0.0);
  for (auto _ : state) {
    auto moving = seed;
    const auto st =
        objectConsensus(c.points, in.member, moving, ObjectParams{}, nullptr, nullptr, rules);
    benchmark::DoNotOptimize(st.objects);
  }
}

void BM_ComponentWidths(benchmark::State& state) {
  // Rule 2's width (doc/OBJECTS.md) of every component of the scan's grouping, which
  // BM_ObjectConsensus includes: its share of that stage.
  const auto& in = inputs();
  const auto& c = in.scans[in.center];
  ObjectComponents cc;
  groupObjects(c.points, in.member, ObjectParams{}.voxel, cc, ringReach(ObjectParams{}, 0.0));
  for (auto _ : state) {
    const std::vector<float> w = componentWidths(cc, ObjectParams{}.foot_height);
    benchmark::DoNotOptimize(w.data());
  }
  state.counters["voxels"] = static_cast<double>(cc.voxels.size());
}

void BM_FreeSpaceInsert(benchmark::State& state) {
  // The window's 21 scans into a fresh map: time per scan.
  const auto& in = inputs();
  for (auto _ : state) {
    FreeSpaceMap m{MapParams{}};
    for (std::size_t i = 0; i < in.scans.size(); ++i)
      m.insertScan(in.scans[i].points, in.scans[i].pose, static_cast<int64_t>(i));
    benchmark::DoNotOptimize(m.blocks());
  }
  state.counters["scans"] = static_cast<double>(in.scans.size());
}

void BM_FreeSpaceInsertKnownArea(benchmark::State& state) {
  // The same scans again into a map that already holds them (no new blocks): time per scan.
  const auto& in = inputs();
  FreeSpaceMap m{MapParams{}};
  int64_t k = 0;
  for (const auto& s : in.scans) m.insertScan(s.points, s.pose, k++);
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& s = in.scans[i++ % in.scans.size()];
    m.insertScan(s.points, s.pose, k++);
  }
  state.counters["blocks"] = static_cast<double>(m.blocks());
}

// DESIGN §2e, the map's decision as its forward pass makes it (OutputWriter::writeMaps), one scan
// an iteration, on a map that holds the 21 scans: /0 every map point's free-space verdict
// (FreeSpaceMap::Lookup, removedByPolicy), /1 the objects' grouping (groupObjects), /2 the
// objects' rules on that grouping (MapObjectConsensus::decide). Map points: every return above
// the road within 50 m, in the world frame.
struct MapInputs {
  FreeSpaceMap map{MapParams{}};
  std::vector<std::vector<PointXYZI>> world;
  std::vector<std::vector<uint8_t>> member, removed;
  std::vector<ObjectComponents> groups;
};

const MapInputs& mapInputs() {
  static const MapInputs in = [] {
    MapInputs r;
    const auto& base = inputs();
    for (std::size_t i = 0; i < base.scans.size(); ++i)
      r.map.insertScan(base.scans[i].points, base.scans[i].pose, static_cast<int64_t>(i));
    for (std::size_t i = 0; i < base.scans.size(); ++i) {
      const Scan& s = base.scans[i];
      auto& w = r.world.emplace_back();
      for (const auto& p : s.points)
        if (p.z > -1.4f && std::abs(p.x) <= 50 && std::abs(p.y) <= 50) {
          const Eigen::Vector3f q = (s.pose * p.xyz().cast<double>()).cast<float>();
          w.push_back({q.x(), q.y(), q.z(), p.intensity});
        }
      r.member.emplace_back(w.size(), 1);
      auto& gone = r.removed.emplace_back();
      FreeSpaceMap::Lookup look(r.map);
      for (const auto& q : w)
        gone.push_back(removedByPolicy(look(q.xyz()), static_cast<int64_t>(i), r.map.params()));
      groupObjects(w, r.member.back(), ObjectParams{}.voxel, r.groups.emplace_back(),
                   ringReach(ObjectParams{}, 0.0));
    }
    return r;
  }();
  return in;
}

void BM_MapDecision(benchmark::State& state) {
  const auto& in = mapInputs();
  const std::size_t n = in.world.size();
  MapObjectConsensus consensus(ObjectParams{}, 0, mapObjectOverlap(in.map.params()));
  ObjectComponents groups;
  std::vector<uint8_t> gone;
  std::size_t points = 0, removed = 0, k = 0;
  for (auto _ : state) {
    const std::size_t i = k % n;
    const auto& w = in.world[i];
    points += w.size();
    if (state.range(0) == 0) {
      FreeSpaceMap::Lookup look(in.map);
      gone.clear();
      for (const auto& q : w)
        gone.push_back(removedByPolicy(look(q.xyz()), static_cast<int64_t>(i), in.map.params()));
    } else if (state.range(0) == 1) {
      consensus.group(w, in.member[i], ringReach(ObjectParams{}, 0.0), groups);
    } else {
      gone = in.removed[i];
      consensus.decide(static_cast<int64_t>(k), 1.0, ringReach(ObjectParams{}, 0.0), w,
                       in.member[i], gone, w.size(), &in.groups[i]);
    }
    for (const uint8_t g : gone) removed += g;
    ++k;
  }
  state.counters["points"] = benchmark::Counter(double(points), benchmark::Counter::kAvgIterations);
  state.counters["removed"] =
      benchmark::Counter(double(removed), benchmark::Counter::kAvgIterations);
}

}  // namespace

BENCHMARK(BM_BeamIndex)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Grazing)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MovingTest)->Arg(0)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Ground)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SensorChecks)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Registration)->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DuplicateFilter)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ObjectConsensus)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ComponentWidths)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FreeSpaceInsert)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FreeSpaceInsertKnownArea)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MapDecision)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) {
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--data" && i + 1 < argc)
      g_data = argv[++i];
    else
      rest.push_back(argv[i]);
  }
  int n = static_cast<int>(rest.size());
  benchmark::Initialize(&n, rest.data());
  if (benchmark::ReportUnrecognizedArguments(n, rest.data())) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
