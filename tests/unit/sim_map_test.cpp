// SPDX-License-Identifier: BSD-3-Clause
// The clean map on simulated hard cases with exact truth (issue #12, item 4): slow movers beside a
// standing ego, a car that stops for 5 s, a parked car that leaves, a queue that stops and goes;
// and the MRPT map layer deciding as the app's maps.
// Each run goes through the pipeline and the OutputWriter as the app does; static_map_full.ply is
// then scored the benchmark's way (DESIGN §5: a truth point is kept if the map has a point within
// 0.05 m, truth within 50 m horizontally of its sensor), per kind of truth point. Bounds sit a
// little below the values measured (doc/BENCHMARK.md, "Clean map: simulated hard cases").
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <set>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/map_score.h"
#include "cleanmap/core/sensor.h"
#include "cleanmap/io/output.h"
#include "cleanmap/io/ply.h"
#include "cleanmap/maps/moving_objects_map.h"
#include "cleanmap/pipeline/laser_pipeline.h"
#include "cleanmap/sim/world.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

sim::Scenario scenario(const std::string& name) {
  return sim::loadScenario(
      (fs::path(CLEANMAP_SOURCE_DIR) / "datasets/scenarios" / (name + ".ini")).string());
}

// The shipped scenario seen by another lidar (its preset's rings and azimuth step).
sim::Scenario scenario(const std::string& name, SensorModel m) {
  sim::Scenario sc = scenario(name);
  sc.sensor.model = m;
  sc.sensor.elevations = ringElevations(m);
  sc.sensor.azimuth_step_deg = sensorPreset(m).azimuth_step_deg;
  sc.name += std::string("_") + sensorPreset(m).name;
  return sc;
}

// Truth points by kind: "world" (static scenery and ground), "<mover>" (a mover's points while it
// moves: the map should not hold them) and "<mover>/standing" (a mover's points while it stands,
// static in the truth). "<kind>/vacated" are those of them whose place no mover holds at the last
// frame: only there can the sensor have seen the space empty for good (a truck's side still
// beside the car at the end was never seen through; a queue's next car fills the space again).
struct MapCase {
  std::map<std::string, MapScore> kinds;
  double kept(const std::string& k) const { return kinds.at(k).sa(); }
  double removed(const std::string& k) const { return kinds.at(k).da(); }
};

MapCase runMapCase(const sim::Scenario& sc, const PipelineParams& params, const std::string& tag) {
  const fs::path out = test::scratchDir(sc.name + "_" + tag);
  fs::remove_all(out);
  // The truth points scored, kept from the frames as they are simulated: world position, kind
  // (index into `kinds`), moving, and whether a mover's point lies outside every mover's box at
  // the last frame (its "/vacated" kind).
  struct Truth {
    Eigen::Vector3f p;
    uint16_t kind;
    bool moving, vacated;
  };
  std::vector<Truth> truth;
  std::vector<std::string> kinds;
  std::map<std::string, uint16_t> kind_ids;
  const sim::World w_end(sc, double(sc.frames - 1) / sc.rate_hz);
  auto inside_at_end = [&](const Eigen::Vector3d& p) {  // any mover's box at the last frame
    for (const auto& b : w_end.solids())
      if (b.surface == sim::Surface::kMover && b.kind == sim::Solid::kBox) {
        const Eigen::Vector3d d = p - b.center;
        const double u = b.c * d.x() + b.s * d.y(), v = -b.s * d.x() + b.c * d.y();
        constexpr double kMargin = 0.15;  // the map's 0.05 m match and the voxel's size
        if (std::abs(u) <= b.half.x() + kMargin && std::abs(v) <= b.half.y() + kMargin &&
            std::abs(d.z()) <= b.half.z() + kMargin)
          return true;
      }
    return false;
  };
  auto kindId = [&](const std::string& kind) {
    const auto [it, fresh] = kind_ids.try_emplace(kind, uint16_t(kinds.size()));
    if (fresh) kinds.push_back(kind);
    return it->second;
  };
  auto keepTruth = [&](const sim::SimScan& s) {
    const sim::World w(sc, s.time);
    std::vector<int> ids(2 * w.solids().size(), -1);  // per solid, standing and moving
    for (std::size_t i = 0; i < s.points.size(); ++i) {
      const uint32_t l = s.labels[i];
      const auto& p = s.points[i];
      if ((l != 9 && l != 251) || double(p.x) * p.x + double(p.y) * p.y > 50.0 * 50.0) continue;
      const int j = s.solid[i];
      const bool mover = j >= 0 && w.solids()[j].surface == sim::Surface::kMover;
      uint16_t kind = 0;
      if (!mover) {
        kind = kindId("world");
      } else {
        int& id = ids[2 * j + (l == 251)];
        if (id < 0) id = kindId(w.solids()[j].name + (l == 251 ? "" : "/standing"));
        kind = uint16_t(id);
      }
      const Eigen::Vector3d pw = s.pose * p.xyz().cast<double>();
      truth.push_back({pw.cast<float>(), kind, l == 251, mover && !inside_at_end(pw)});
    }
  };
  {
    io::OutputWriter writer(out.string(), "sim:" + sc.name, params);
    LaserPipeline pipe(params, [&](ScanResult&& r) { writer.write(r, std::nullopt); });
    for (int k = 0; k < sc.frames; ++k) {
      sim::SimScan s = sim::simulateScan(sc, k, 2);
      keepTruth(s);
      pipe.push(sim::frameOf(std::move(s), k));
    }
    pipe.finish();
    writer.finish(0.0, pipe.freeSpace());
  }
  std::vector<Eigen::Vector3f> map;
  for (const auto& p : io::readPly((out / "static_map_full.ply").string())) map.push_back(p.xyz());
  const RadiusIndex index(std::move(map), 0.05);
  std::map<std::string, MapScorer> scorers;
  auto scorer = [&](const std::string& k) -> MapScorer& {
    return scorers.try_emplace(k, index).first->second;
  };
  std::vector<MapScorer*> by_id, vacated_by_id(kinds.size(), nullptr);
  for (const auto& k : kinds) by_id.push_back(&scorer(k));
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const Truth& t = truth[i];
    index.prefetchAhead(i, truth.size(), [&](std::size_t k) { return truth[k].p; });
    by_id[t.kind]->add(t.p, t.moving);
    if (!t.vacated) continue;
    if (!vacated_by_id[t.kind]) vacated_by_id[t.kind] = &scorer(kinds[t.kind] + "/vacated");
    vacated_by_id[t.kind]->add(t.p, t.moving);
  }
  MapCase res;
  for (const auto& [k, sc_k] : scorers) {
    res.kinds[k] = sc_k.score();
    const MapScore& m = sc_k.score();
    if (m.moving_total)
      std::printf("  %s (%s): %s removed %.4f of %llu moving points\n", sc.name.c_str(),
                  tag.c_str(), k.c_str(), m.da(), (unsigned long long)m.moving_total);
    if (m.static_total)
      std::printf("  %s (%s): %s kept %.4f of %llu static points\n", sc.name.c_str(), tag.c_str(),
                  k.c_str(), m.sa(), (unsigned long long)m.static_total);
  }
  return res;
}

PipelineParams withPolicy(MapPolicy p) {
  PipelineParams params;
  params.map.policy = p;
  return params;
}

}  // namespace

TEST(SimMap, TruckCrawlingBesideAStandingEgo) {
  // The truck's side slides along itself: free space is seen only where its rear has passed
  // (vacated_scans) and where its front came (arrived_scans); the windowed test finds none of it
  // (recall 0, doc/BENCHMARK.md). The part between, occupied in every scan, goes with those ends:
  // the map decides per object (static_map.objects, DESIGN §2e).
  const auto r = runMapCase(scenario("truck_crawl"), {}, "default");
  EXPECT_GE(r.removed("truck/vacated"), 0.90);  // measured 0.960 (0.687 per voxel, 0.12 without
                                                // vacated_scans)
  EXPECT_GE(r.removed("truck"), 0.95);  // measured 0.991 (0.143 per voxel; 0.351 with the arrival)
  EXPECT_GE(r.kept("world"), 0.999);    // measured 1.0000
  // Per voxel, and without rule 7 (doc/OBJECTS.md), which finds the truck by its side's end in
  // the scans' labels (0.535 per voxel with it): what the map's objects do alone.
  PipelineParams per_voxel;
  per_voxel.map.objects = false;
  per_voxel.object.measure = false;
  const auto v = runMapCase(scenario("truck_crawl"), per_voxel, "per_voxel");
  EXPECT_LE(v.removed("truck"), 0.5);  // measured 0.351: the side's middle never left
}

TEST(SimMap, TruckCrawlingSeenByAnHdl32) {
  // The same truck seen by an HDL-32E: its removed share stays under moving_fraction (18 %) in
  // the first 12 scans and reaches it in the 13th. Rule 4 forwards then holds it to the end, but
  // the first 12 scans kept it whole and their points cover the side the truck slides along
  // (map DA 0.32); rule 4 backwards (DESIGN §2e "Objects") takes them from the 13th down.
  const auto r = runMapCase(scenario("truck_crawl", SensorModel::kHdl32), {}, "default");
  EXPECT_GE(r.removed("truck"), 0.95);  // measured 0.990 (0.984 before rule 4 asked its
                                        // ends, 0.324 forwards only)
  EXPECT_GE(r.kept("world"), 0.999);    // measured 1.0000
}

TEST(SimMap, TruckCrawlingAtHalfSpeed) {
  // The truck at 0.6 m/s. The scans' labels find it by its side's ends (doc/OBJECTS.md rule 7,
  // "A side's ends"; recall 0 before). Without rule 7, what the map does alone: in its first 20
  // scans only its rear, seen at a grazing angle, is seen vacated later (2-9 % of its points,
  // under static_fraction), so rule 4 cannot take those scans back from the first that took it
  // whole; their points cover the side it slides along (map DA 0.25). Each of them stands in the
  // voxels of the whole truck a scan later: rule 5 (static_map.object_overlap, DESIGN §2e
  // "Objects") takes them.
  sim::Scenario sc = scenario("truck_crawl");
  for (auto& m : sc.movers) m.speed *= 0.5;
  sc.name += "_half";
  const auto r = runMapCase(sc, {}, "default");
  EXPECT_GE(r.removed("truck"), 0.95);  // measured 0.992
  EXPECT_GE(r.kept("world"), 0.999);    // measured 1.0000
  PipelineParams unmeasured;
  unmeasured.object.measure = false;
  const auto u = runMapCase(sc, unmeasured, "unmeasured");
  EXPECT_GE(u.removed("truck"), 0.95);  // measured 0.991
  EXPECT_GE(u.kept("world"), 0.999);
  PipelineParams no_overlap = unmeasured;
  no_overlap.map.object_overlap = 0;
  const auto o = runMapCase(sc, no_overlap, "no_overlap");
  EXPECT_LE(o.removed("truck"), 0.5);  // measured 0.25
}

TEST(SimMap, ParkedCarsPassedCloseKeepTheirRoofs) {
  // The default street's parked cars, passed at 1.4 m: their roofs (1.5 m, under the 1.73 m
  // sensor) lie in the lower part of their voxels, through which the rings just above pass on to
  // the facades; seen empty, the roofs went, and with them, past 20 %, the whole cars in some
  // scans. Beams grazing a flat surface mark nothing within `margin` of it (static_map.flat_slope,
  // DESIGN §2e).
  const auto r = runMapCase(scenario("default"), {}, "default");
  EXPECT_GE(r.kept("world"), 0.999);  // measured 0.9998
  PipelineParams flat_off;
  flat_off.map.flat_slope = 0;
  const auto o = runMapCase(scenario("default"), flat_off, "flat_off");
  EXPECT_LE(o.kept("world"), 0.996);  // measured 0.9836 (rule 5 takes such a car in more scans)
}

TEST(SimMap, ParkedCarsPassedCloseByAVlp16KeepTheirRoofs) {
  // The same with a VLP-16 (rings 2 degrees apart, 2 m minimum range) on parked_leaves: the car
  // parked 1.6 m beside the path returns its roof by one ring, the rings below it meet the car
  // within 2 m and return nothing, so no ring there is flat and the ring above grazed the roof's
  // voxels, seen empty; the object rules then took the car whole in many scans. A return
  // with nothing below it is taken to lie on a level surface (DESIGN §2e, grazing beams).
  const auto r = runMapCase(scenario("parked_leaves", SensorModel::kVlp16), {}, "default");
  EXPECT_GE(r.kept("world"), 0.995);          // measured 0.9999 (0.9472 before)
  EXPECT_GE(r.removed("leaving_car"), 0.85);  // measured 0.9003 (0.9003 before)
}

TEST(SimMap, ParkedCarsSidesStayWithAnOusterAt512Columns) {
  // The default street seen by an OS1-64 at 512 columns (0.70 degrees). A parked car's side 1.5 m
  // beside the path, seen from 20 m, is met at 4 degrees: its returns lie 3 m apart along it, and
  // each beam runs within `margin` of it for 4 m before its end, through the side's voxels
  // between the returns' hit_inflate: seen empty, the sides' upper halves went (2,497 points in
  // scan 35). Such a beam marks nothing within margin / sin(alpha) of its end (grazing sides,
  // DESIGN §2e). The moving cyclist and pedestrian still go.
  sim::Scenario sc = scenario("default", SensorModel::kOs1_64);
  sc.sensor.azimuth_step_deg = 360.0 / 512;
  sc.name += "_512";
  const auto r = runMapCase(sc, {}, "default");
  EXPECT_GE(r.kept("world"), 0.995);  // measured 0.9980
  EXPECT_GE(r.removed("cyclist"), 0.9);
  EXPECT_GE(r.removed("pedestrian"), 0.9);
  PipelineParams off;
  off.map.grazing_sides = false;
  EXPECT_LE(runMapCase(sc, off, "sides_off").kept("world"), 0.98);  // measured 0.9664
}

TEST(SimMap, CarStoppingFor5sThenLeaving) {
  const auto r = runMapCase(scenario("car_stops_5s"), {}, "default");
  EXPECT_GE(r.removed("stopping_car"), 0.90);        // measured 0.934
  EXPECT_LE(r.kept("stopping_car/standing"), 0.25);  // measured 0.122 (0.80 without vacated)
  EXPECT_GE(r.kept("world"), 0.995);                 // measured 0.9987
}

TEST(SimMap, ParkedCarThatDrivesOff) {
  const auto t =
      runMapCase(scenario("parked_leaves"), withPolicy(MapPolicy::kTransient), "transient");
  EXPECT_LE(t.kept("leaving_car/standing"), 0.20);    // measured 0.131: it stood, then left
  EXPECT_GE(t.removed("leaving_car/vacated"), 0.90);  // measured 0.929
  EXPECT_GE(t.kept("world"), 0.985);                  // measured 0.9958
  const auto m = runMapCase(scenario("parked_leaves"), withPolicy(MapPolicy::kMoving), "moving");
  EXPECT_GE(m.kept("leaving_car/standing"), 0.95);  // measured 0.988: static while scanned
  EXPECT_GE(m.kept("world"), 0.99);                 // measured 0.9999
}

TEST(SimMap, CarThatArrivesAndParks) {
  // car_stops_5s's car stops after 2 s and stays: 6 s parked. `transient` removes what came and
  // stood (arrived_scans, then its object) as it removes what stood and left; `moving` keeps
  // it (with the arrival rule under `moving` too, about a third of the parked car went).
  sim::Scenario sc = scenario("car_stops_5s");
  sc.name = "car_arrives_parks";
  for (auto& m : sc.movers) m.stop = std::pair{2.0, 100.0};
  const auto t = runMapCase(sc, withPolicy(MapPolicy::kTransient), "transient");
  EXPECT_GE(t.removed("stopping_car"), 0.90);        // measured 0.944
  EXPECT_LE(t.kept("stopping_car/standing"), 0.25);  // measured 0.064: it came, then stood
  EXPECT_GE(t.kept("world"), 0.995);                 // measured 0.9989
  const auto m = runMapCase(sc, withPolicy(MapPolicy::kMoving), "moving");
  EXPECT_GE(m.kept("stopping_car/standing"), 0.95);  // measured 0.9995
  EXPECT_GE(m.kept("world"), 0.999);                 // measured 1.0000
}

TEST(SimMap, QueueThatStopsAndGoes) {
  // The next car of the queue fills the space the one before left, so the lane is seen empty in
  // about a third of the scans (the gaps): under free_ratio. But each gap is a run of empty
  // scans between two returns (between_scans), which the windowed test cannot see (recall 0.06).
  // The last car's place at the end was never seen empty; per voxel queue_3 kept most of its
  // points, per object it goes with the parts of it that came.
  const auto r = runMapCase(scenario("queue_stop_go"), {}, "default");
  // Decided per object (DESIGN §2e), each car goes whole where enough of it came or left.
  EXPECT_GE(r.removed("queue_1"), 0.93);          // measured 0.986 (0.967 per voxel; 0.297 without
                                                  // the runs)
  EXPECT_GE(r.removed("queue_2"), 0.90);          // measured 0.970 (0.895; 0.279)
  EXPECT_GE(r.removed("queue_1/vacated"), 0.90);  // measured 0.967 (0.928)
  EXPECT_GE(r.removed("queue_2/vacated"), 0.85);  // measured 0.938 (0.789)
  EXPECT_GE(r.removed("queue_3/vacated"), 0.85);  // measured 0.925 (0.608)
  EXPECT_GE(r.kept("world"), 0.999);              // measured 1.0000
}

TEST(SimMap, QueueAtThreeMetresPerSecond) {
  // The same queue at 3 m/s: a 1.9-2 m gap between two cars passes a voxel of the lane in 6-7
  // scans, of which each car's own returns protect 0.32 m (hit_inflate) and the beam's margin
  // another: the lane is seen empty for 3-4 scans between two returns (between_scans = 3). With
  // a run of 5 needed (vacated_scans' length, which the rule took before), queue_1 / 2 / 3/vacated
  // were removed 0.195 / 0.272 / 0.727 and the whole queue's map DA was 0.36 (0.89 at 2 m/s).
  sim::Scenario sc = scenario("queue_stop_go");
  sc.name += "_3ms";
  for (auto& m : sc.movers) m.speed = 3.0;
  const auto r = runMapCase(sc, {}, "default");
  EXPECT_GE(r.removed("queue_1/vacated"), 0.93);  // measured 0.995 (0.981 per voxel)
  EXPECT_GE(r.removed("queue_2/vacated"), 0.88);  // measured 0.983 (0.927 per voxel)
  EXPECT_GE(r.removed("queue_3/vacated"), 0.78);  // measured 0.972 (0.833 per voxel)
  EXPECT_GE(r.kept("world"), 0.999);              // measured 1.0000
}

TEST(SimMap, QueueSeenByLidarsSparserThanTheFreeSpaceBins) {
  // Issue #15 and the map: the same queue seen by an Ouster OS1-128 at 1024 columns (0.35 degrees
  // between columns) and a VLP-16 (0.2). The free-space walk leaves out beams near the sensor on
  // the assumption that every azimuth bin holds one; with bins narrower than the lidar's step it
  // left voxels of the lane 2-4 m away unvisited: queue_1 / queue_2 removed 0.508 / 0.490 with
  // the OS1-128 (map DA 0.50 against 0.92 with the HDL-64E; doc/BENCHMARK.md), 0.944 / 0.753 with
  // the VLP-16. The bins now follow the lidar (DESIGN §2e): measured 0.977 / 0.902 and 0.988 /
  // 0.799, the world kept 1.0000 by both.
  for (const SensorModel m : {SensorModel::kOs1_128, SensorModel::kVlp16}) {
    const auto r = runMapCase(scenario("queue_stop_go", m), {}, "default");
    const std::string lidar = sensorPreset(m).name;
    EXPECT_GE(r.removed("queue_1"), 0.90) << lidar;
    EXPECT_GE(r.removed("queue_2"), 0.75) << lidar;
    EXPECT_GE(r.kept("world"), 0.995) << lidar;
  }
}

TEST(SimMap, TheMapsDecisionIsTheSameWithOneOrTwoThreads) {
  // With two threads the map's final decision reads and looks up the next scan beside this one's
  // objects (OutputWriter::writeMaps), and its backward pass reads the scan before, dropping it
  // where the memory empties and that scan has no whole objects (once in parked_leaves, not in
  // truck_crawl, counted with a throw-away print): the same files, byte for byte, as one thread
  // writes.
  for (const char* name : {"truck_crawl", "parked_leaves"}) {
    sim::Scenario sc = scenario(name);
    sc.frames = 30;
    std::map<int, std::map<std::string, std::string>> files;
    for (const int threads : {1, 2}) {
      PipelineParams params;
      params.threads = threads;
      sc.name = std::string(name) + "_threads" + std::to_string(threads);
      runMapCase(sc, params, "default");
      const fs::path out = fs::path(CLEANMAP_TEST_SCRATCH_DIR) / (sc.name + "_default");
      for (const auto& e : fs::recursive_directory_iterator(out)) {
        const std::string rel = fs::relative(e.path(), out).string();
        if (!e.is_regular_file() || rel.rfind("report", 0) == 0 || rel == "params.ini") continue;
        std::ifstream in(e.path(), std::ios::binary);
        files[threads][rel].assign(std::istreambuf_iterator<char>(in), {});
      }
    }
    ASSERT_GT(files[1].count("static_map_full.ply"), 0u) << name;
    ASSERT_GT(files[1].count("map_labels/000029.label"), 0u) << name;
    EXPECT_EQ(files[1].size(), files[2].size()) << name;
    for (const auto& [rel, bytes] : files[1]) EXPECT_TRUE(files[2][rel] == bytes) << name << rel;
  }
}

TEST(SimMap, TheMapLayerDecidesPerObjectAsTheAppsMaps) {
  // DESIGN §4b: the MRPT map layer (cleanmap_moving) decides its static map per rigid object as
  // the app's maps do (static_map.objects, DESIGN §2e). With every point its own entry
  // (map_voxel 0) its static points are static_map_full.ply's, point for point; at its default
  // 0.1 m voxels the truck crawling beside the standing ego goes from the layer too.
  sim::Scenario sc = scenario("truck_crawl");
  sc.name = "truck_crawl_layer";
  runMapCase(sc, {}, "default");
  const auto sorted = [](std::vector<Eigen::Vector3f> v) {
    std::sort(v.begin(), v.end(), [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
      return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    });
    return v;
  };
  const auto xyz = [](const std::vector<PointXYZI>& pts) {
    std::vector<Eigen::Vector3f> v;
    for (const auto& p : pts) v.push_back(p.xyz());
    return v;
  };
  const auto app = sorted(xyz(io::readPly(
      (fs::path(CLEANMAP_TEST_SCRATCH_DIR) / (sc.name + "_default") / "static_map_full.ply")
          .string())));
  // The frames, simulated once for the four layers below, and the 0.1 m voxels of the truck's
  // points (none shared with the scenery's) and the scenery's.
  std::vector<Frame> frames;
  std::set<uint64_t> truck, world;
  for (int k = 0; k < sc.frames; ++k) {
    sim::SimScan s = sim::simulateScan(sc, k, 2);
    const sim::World w(sc, s.time);
    for (std::size_t i = 0; i < s.points.size(); ++i) {
      if (s.labels[i] != 9 && s.labels[i] != 251) continue;  // ground aside: always kept
      const bool mover = s.solid[i] >= 0 && w.solids()[s.solid[i]].surface == sim::Surface::kMover;
      const Eigen::Vector3f p = (s.pose * s.points[i].xyz().cast<double>()).cast<float>();
      (mover ? truck : world).insert(cellKeyOf(p.x(), p.y(), p.z(), 10.0f));
    }
    frames.push_back(sim::frameOf(std::move(s), k));
  }
  for (const uint64_t k : world) truck.erase(k);
  const auto layer = [&](const PipelineParams& params, double voxel,
                         std::size_t object_scans = 0) {  // 0: all
    auto m = std::make_unique<cleanmap_maps::CMovingObjectsMap>(params, voxel);
    m->setObjectScans(object_scans);
    for (const Frame& f : frames) m->insertFrame(Frame(f));
    m->flush();
    return m;
  };
  const auto exact = layer({}, 0.0);
  const auto points = sorted(xyz(exact->staticPoints()));
  ASSERT_GT(app.size(), 100000u);
  EXPECT_EQ(points.size(), app.size());
  EXPECT_TRUE(points == app) << "the layer's static points differ from static_map_full.ply's";
  EXPECT_GT(exact->objectPoints(), 0u);

  const auto keptShare = [](const std::vector<PointXYZI>& kept,
                            const std::vector<PointXYZI>& removed, const std::set<uint64_t>& in) {
    std::size_t k = 0, r = 0;
    for (const auto& p : kept) k += in.count(cellKeyOf(p.x, p.y, p.z, 10.0f));
    for (const auto& p : removed) r += in.count(cellKeyOf(p.x, p.y, p.z, 10.0f));
    return k + r ? double(k) / double(k + r) : 1.0;
  };
  // The layer's modes against each other without rule 7 (doc/OBJECTS.md), which finds the truck
  // in the scans' labels (per voxel it then keeps 0.380 of the truck's voxels, as with 20 scans'
  // objects): what the map's objects do alone.
  PipelineParams unmeasured;
  unmeasured.object.measure = false;
  const auto by_object = layer(unmeasured, 0.1);
  PipelineParams per_voxel = unmeasured;
  per_voxel.map.objects = false;
  const auto by_voxel = layer(per_voxel, 0.1);
  const double truck_obj = keptShare(by_object->staticPoints(), by_object->removedPoints(), truck);
  const double truck_vox = keptShare(by_voxel->staticPoints(), by_voxel->removedPoints(), truck);
  std::printf("  layer: truck voxels kept %.4f per object, %.4f per voxel\n", truck_obj, truck_vox);
  EXPECT_LE(truck_obj, 0.05);  // measured 0.018
  EXPECT_GE(truck_vox, 0.2);   // measured 0.289: the side's middle never left
  EXPECT_GE(keptShare(by_object->staticPoints(), by_object->removedPoints(), world), 0.999);

  // map_object_scans bounds the layer's memory: with the last 20 scans' objects kept, an older
  // scan is decided as it leaves (rule 4 forwards, the free space seen by then); a voxel its
  // objects kept is left to the free space's rule. Less hindsight than the whole run: the truck
  // goes less than with all 80 scans, but more than per voxel.
  const auto bounded = layer(unmeasured, 0.1, 20);
  EXPECT_LT(bounded->objectPoints() * 3, by_object->objectPoints());  // 20 of 80 scans
  const double truck_bounded = keptShare(bounded->staticPoints(), bounded->removedPoints(), truck);
  std::printf("  layer: truck voxels kept %.4f with 20 scans' objects\n", truck_bounded);
  EXPECT_LT(truck_bounded, truck_vox);  // measured 0.243
  EXPECT_GE(keptShare(bounded->staticPoints(), bounded->removedPoints(), world), 0.999);
}

TEST(SimMap, ASparseLidarsWalkerGoesFromTheMapWithTheRingPool) {
  // doc/OBJECTS.md rule 1, object.ring_pool: `poles_drift`'s walker seen by a VLP-16 comes in two
  // rings 0.9 m apart; the map's objects (DESIGN §2e) kept his legs' ring as a slice of its own in
  // many scans. Joined across the rings (the spooled sensor position and ring step) he goes
  // whole more often. (Rule 6's stacks do some of that where both of his slices are flagged in
  // part, 0.679 -> 0.737 without the pool: off too, to show the pool alone.)
  const sim::Scenario sc = scenario("poles_drift", SensorModel::kVlp16);
  PipelineParams no_pool;
  no_pool.object.ring_pool = 0;
  no_pool.object.roofs = false;
  const auto off = runMapCase(sc, no_pool, "pool_off");
  const PipelineParams pool;  // ring_pool 1 m, the default
  const auto on = runMapCase(sc, pool, "pool_on");
  EXPECT_LE(off.removed("walker"), 0.72);                  // measured 0.679
  EXPECT_GE(on.removed("walker"), 0.78);                   // measured 0.817
  EXPECT_GE(on.kept("world"), off.kept("world") - 0.001);  // measured 0.9718 and 0.9719
  // The MRPT map layer (map_voxel 0, every scan's objects) decides as the app's maps, point for
  // point (DESIGN §4b).
  cleanmap_maps::CMovingObjectsMap layer(pool, 0.0);
  layer.setObjectScans(0);
  for (int k = 0; k < sc.frames; ++k)
    layer.insertFrame(sim::frameOf(sim::simulateScan(sc, k, 2), k));
  layer.flush();
  const auto sorted = [](const std::vector<PointXYZI>& pts) {
    std::vector<Eigen::Vector3f> v;
    for (const auto& p : pts) v.push_back(p.xyz());
    std::sort(v.begin(), v.end(), [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
      return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    });
    return v;
  };
  const auto app = sorted(io::readPly(
      (fs::path(CLEANMAP_TEST_SCRATCH_DIR) / (sc.name + "_pool_on") / "static_map_full.ply")
          .string()));
  const auto points = sorted(layer.staticPoints());
  EXPECT_EQ(points.size(), app.size());
  EXPECT_TRUE(points == app) << "the layer's static points differ from static_map_full.ply's";
}
