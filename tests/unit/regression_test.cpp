// SPDX-License-Identifier: BSD-3-Clause
// Accuracy on the labelled KITTI sets with default parameters and given poses (DESIGN §5, points
// in the 30 m crop, ignore labels excluded). Bounds sit a little below what we measured
// (doc/BENCHMARK.md) so a regression fails; where issue #3's bar is met, the bar is asserted too.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "cleanmap/core/metrics.h"
#include "cleanmap/eval/evaluate.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/io/output.h"
#include "cleanmap/pipeline/laser_pipeline.h"
#include "test_data.h"

using namespace cleanmap;

namespace {

// FNV-1a 64 over bytes, continued from h.
uint64_t fnv(const void* data, std::size_t n, uint64_t h) {
  const auto* b = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 0x100000001b3ull;
  return h;
}

/// Digests of everything a run writes: the label files in scan order and the bodies of
/// static_map.ply, static_map_full.ply and dynamic.ply (their points, as written).
struct OutputDigest {
  uint64_t labels = 0xcbf29ce484222325ull, compact = labels, full = labels, moving = labels;
  void add(const ScanResult& r) {
    labels = fnv(r.labels.data(), r.labels.size() * sizeof(uint32_t), labels);
    compact = fnv(r.static_compact.data(), r.static_compact.size() * sizeof(PointXYZI), compact);
    full = fnv(r.static_full.data(), r.static_full.size() * sizeof(PointXYZI), full);
    moving = fnv(r.moving.data(), r.moving.size() * sizeof(PointXYZI), moving);
  }
};

MosCounts runSet(const std::string& set, OutputDigest* digest = nullptr,
                 const PipelineParams& params = PipelineParams{}, bool images = false,
                 std::size_t* relabelled_moving = nullptr,
                 std::vector<MosCounts>* per_scan = nullptr) {
  auto seq = io::KittiSequence::open(test::dataDir() + "/" + set);
  MosCounts total;
  if (per_scan) per_scan->assign(seq.size(), MosCounts{});
  LaserPipeline pl(params, [&](ScanResult&& r) {
    const Labels truth = seq.loadLabels(r.index, r.labels.size());
    const MosCounts c = compareLabels(r.labels, truth, set);
    total += c;
    if (per_scan) (*per_scan)[r.index] += c;
    if (relabelled_moving)  // the camera's relabellings of truly moving points
      for (const uint32_t i : r.relabelled_index)
        *relabelled_moving += gtClass(truth[i]) == GtClass::kMoving;
    if (digest) digest->add(r);
  });
  if (images) pl.setCamera(seq.camera());
  for (std::size_t i = 0; i < seq.size(); ++i) pl.push(seq.frame(i));
  pl.finish();
  return total;
}

// The set with each frame and its labels changed by `edit(index, frame, labels)` before the
// pipeline sees it (the labels come in per point of the frame's original scan). `poses`, if
// given, receives (used, given) per scan.
using FrameEdit = std::function<void(std::size_t, Frame&, Labels&)>;
MosCounts runSetEdited(
    const std::string& set, const FrameEdit& edit, const PipelineParams& params = PipelineParams{},
    std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>>* poses = nullptr) {
  auto seq = io::KittiSequence::open(test::dataDir() + "/" + set);
  std::vector<Labels> truth(seq.size());
  std::vector<Eigen::Isometry3d> given(seq.size());
  MosCounts total;
  LaserPipeline pl(params, [&](ScanResult&& r) {
    total += compareLabels(r.labels, truth[r.index], set);
    if (poses) poses->emplace_back(r.pose, given[r.index]);
  });
  for (std::size_t i = 0; i < seq.size(); ++i) {
    Frame f = seq.frame(i);
    given[i] = f.scan.pose;
    truth[i] = seq.loadLabels(i, f.scan.original_size);
    edit(i, f, truth[i]);
    pl.push(std::move(f));
  }
  pl.finish();
  return total;
}

// The set as a 16-ring lidar would see it: lasers offset, offset + 4, ... of each scan, with
// their labels (test::kittiRingsKept).
// Keeps the points `kept(points)` of each scan and their labels: the kept points are the input.
template <class Kept>
void keepPoints(Frame& f, Labels& truth, Kept&& kept) {
  const Labels all = std::move(truth);
  truth.clear();
  std::vector<PointXYZI> pts;
  for (const std::size_t j : kept(f.scan.points)) {
    pts.push_back(f.scan.points[j]);
    truth.push_back(all[f.scan.originalIndex(j)]);
  }
  f.scan.points = std::move(pts);
  f.scan.original_index.clear();  // the kept points are the input now
  f.scan.original_size = f.scan.points.size();
  f.scan.dropped_invalid = 0;
}

MosCounts runSetSixteenRings(
    const std::string& set, int offset, const PipelineParams& params = PipelineParams{},
    std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>>* poses = nullptr) {
  const auto rings = [offset](std::size_t, Frame& f, Labels& truth) {
    keepPoints(f, truth, [offset](const std::vector<PointXYZI>& p) {
      return test::kittiRingsKept(p, 4, offset);
    });
  };
  return runSetEdited(set, rings, params, poses);
}

// The set with every other column of its scans (test::kittiColumnsKept): an Ouster's 0.35
// degrees between columns at the HDL-64E's rings.
MosCounts runSetEveryOtherColumn(const std::string& set) {
  const auto columns = [](std::size_t, Frame& f, Labels& truth) {
    keepPoints(f, truth,
               [](const std::vector<PointXYZI>& p) { return test::kittiColumnsKept(p, 2); });
  };
  return runSetEdited(set, columns, PipelineParams{}, nullptr);
}

// The set through the pipeline and the OutputWriter as the app runs it (the map cleaned with the
// whole sequence's free space), then static_map_full.ply scored the DynamicMap way (DESIGN §5).
MapScore cleanMapScore(const std::string& set) {
  const std::string gt = test::dataDir() + "/" + set;
  const auto out = test::scratchDir(set + "_run");
  std::filesystem::remove_all(out);
  auto seq = io::KittiSequence::open(gt);
  const PipelineParams params;
  {
    io::OutputWriter writer(out.string(), gt, params);
    LaserPipeline pl(params, [&](ScanResult&& r) { writer.write(r, std::nullopt); });
    for (std::size_t i = 0; i < seq.size(); ++i) pl.push(seq.frame(i));
    pl.finish();
    writer.finish(0.0, pl.freeSpace());
  }
  eval::ResultInput in;
  in.map_path = (out / "static_map_full.ply").string();
  const auto report = eval::evaluate(gt, in, eval::EvalOptions{});
  if (!report.map) throw std::runtime_error(set + ": no map score");
  return *report.map;
}

// Labels and maps byte-identical to a reference run. The references are the digests of the
// files written by `cleanmap <set> -o OUT` at commit ecfd148 (before the renovation of issue #10:
// decide() as named stages, one grid key, one parallel loop), default parameters. A change
// that moves any label or map point fails here; an intended change of results updates these
// numbers in the same commit and says why. Issue #12 changed the full map on purpose: it holds
// the points beyond the 30 m crop within static_map.radius (50 m) too; the other digests stayed.
// Issue #15 changed every digest on purpose: the ground segmentation starts from the ground
// height measured in the scans (sensor.height = auto, 1.81-1.90 m on these sets) instead of
// KITTI's nominal 1.73 m (recall up on all three sets, doc/BENCHMARK.md). The object consensus's
// bodies (doc/OBJECTS.md rule 2) changed highway's on purpose: a car's 129 moving points that
// its component turned static stay moving (IoU 0.8531 -> 0.8543); city and residential stayed.
// Rule 2's foot (the same file) changed highway's and residential's on purpose: a component turned
// moving no longer takes along its low points with nothing of it above them (from a low mount, the
// sidewalk beside a car that leaves); highway 40 points (recall 0.9044 -> 0.9043, IoU 0.8543),
// residential 81 points, all outside the labelled area (label 0); city stayed.
// Rule 2's raised parts (the same file) changed highway's and residential's on purpose: above the
// foot only the parts of a component turned moving that hold a moving point of their own take
// its motion (a walker joined by a sidewalk to a pole and a wall takes neither along); highway
// 253 moving points of a truck's part (recall 0.9043 -> 0.9040, IoU 0.8539), residential 36
// points, all label 0; city stayed.
// The ground's ceiling (ground.cpp, DESIGN §2a) changed every digest on purpose: where only the
// gap's allowance would lift a cell, the lower returns on the way cap it, so the sides of cars
// and trucks beside the blind zone, hedges and a far walker, up to 2.4 m above the road, are no
// longer ground (residential 36,691 points, highway 24,613, city 27,527); they are tested and
// enter the objects. Highway recall 0.9040 -> 0.8895 (a tanker's share in scan 26 falls under
// rule 4's 10 %: 12,736 points; scans 0-25 IoU 0.9053 -> 0.9087), residential precision 0.847 ->
// 0.833, city within 0.001; the clean map's AA 98.73 / 98.65 / 94.28 -> 99.15 / 98.67 / 99.10.
// Rule 4 under static_fraction (doc/OBJECTS.md) changed highway's on purpose: the object the
// previous scan moved whole stays moving where the scans after it see it leave, though under 10 %
// of it tests moving; a car in scans 20-25 and the tanker in scans 26-29 (recall 0.8895 ->
// 0.9751, precision 0.9386 -> 0.9404, IoU 0.9184; scan 29, the last, has no scan after it and
// holds it as it was); city and residential stayed. Held through the last K / 2 scans (too few
// after them to see a vehicle leave; no moving point of its own needed): the VW receding ahead
// at 0.8 m/s in scans 27-29, highway recall 0.9751 -> 0.9800, precision 0.9407, IoU 0.9230.
// Grazing beams in the windowed test, on (DESIGN §2b), with rule 4's far-half leaving test and
// moved match (doc/OBJECTS.md), changed city's and highway's on purpose: at a point on a flat top
// of its own scan a window scan's beam running within margin of a flat surface of its own does
// not vote (roofs and bonnets seen edge-on); an object the previous scan moved whole, also found
// moved, stays moving where half of its points are moving for the far half of the later scans.
// Highway: the car 16 m ahead at 0.6 m/s, seen over the one in front, held in scans 14-29
// (+1,413 points), the tanker's share in scans 23 and 26 under 10 % (9.2 %, was 11.4 %) with
// too little of it in view to be the previous scan's object (-2,303): recall 0.9800 -> 0.9787;
// city precision 0.5800 -> 0.5801; residential stayed.
// Rule 6, a mover's feet (doc/OBJECTS.md), changed every digest but the compact maps' on purpose:
// returns refined to ground whose nearest return above is moving, raised over the road around
// them, go with it (city 421 points, highway 2,385, residential 11: 5 of them a motorcycle's tyres,
// which the labels call ground below 0.10 m). Precision city 0.5801 -> 0.5794, highway 0.9408 ->
// 0.9396, residential 0.8325 -> 0.8244; recall within 0.0003; the map's AA within 0.0001.
void expectDigest(const OutputDigest& d, uint64_t labels, uint64_t compact, uint64_t full,
                  uint64_t moving) {
  EXPECT_EQ(d.labels, labels) << "labels differ from the reference run";
  EXPECT_EQ(d.compact, compact) << "static_map.ply differs from the reference run";
  EXPECT_EQ(d.full, full) << "static_map_full.ply differs from the reference run";
  EXPECT_EQ(d.moving, moving) << "dynamic.ply differs from the reference run";
}

}  // namespace

TEST(Regression, OutputsByteIdenticalToTheReference) {
  for (const char* set : {"kitti_city", "kitti_highway", "kitti_residential"})
    CLEANMAP_REQUIRE_DATASET(set);
  OutputDigest city, highway, residential;
  runSet("kitti_city", &city);
  runSet("kitti_highway", &highway);
  runSet("kitti_residential", &residential);
  // City's and highway's changed with the column links at every lidar (doc/OBJECTS.md rule 1,
  // "Dense columns": a side met at a grazing angle joins its car; there no more than a vehicle's
  // size; evenly spaced, in one line): city 2 false positives more (precision 0.579441 ->
  // 0.579434), highway 47 moving points more and 14 false (IoU 0.93788 -> 0.93793); residential's
  // are the same.
  // City's and highway's changed with a dense lidar's roofs (doc/OBJECTS.md rule 6): city 19
  // returns of moving roofs more, 2 false (precision 0.579433 -> 0.579476, recall 0.99898 ->
  // 0.99919); highway 68 more, 4 false (IoU 0.937925 -> 0.938011); residential's are the same.
  // City's and highway's changed with rule 2's "What it stands on" (doc/OBJECTS.md): a foot's
  // point with nothing of its component over it keeps its label. City 145 false positives fewer,
  // 11 moving returns fewer (precision 0.5795 -> 0.5800, recall 0.9992 -> 0.9991); highway the
  // road under and beside a truck 2-4 m off, 1,544 false positives fewer, 218 moving returns
  // fewer, under 0.3 m over the road behind (precision 0.9403 -> 0.9423, recall 0.9975 ->
  // 0.9972); the full maps hold those returns now; residential's are the same.
  // Every digest changed with the self returns (DESIGN §2.2): the recording car's own returns
  // that the test flagged leave the crop (label 0, in no map): city 695 (false positives 66,641 ->
  // 66,271, precision 0.5800 -> 0.5813), highway 851 (42,823 -> 42,690, 0.9423 -> 0.9424),
  // residential 1,070 (its labels ignore them); none labelled moving on any set, recall the same.
  expectDigest(city, 0x8d792dba690e0597ull, 0x2c2c1f6b327bc1caull, 0xc763f92dfe481300ull,
               0xb133a260b1d06626ull);
  // Highway's changed with rule 4 at the start (doc/OBJECTS.md): scans 0-4 carry back the truck
  // and the car coming up behind the sensor; highway's and residential's with rule 4 backwards
  // throughout: 36 more returns carried back on highway, 36 beyond 50 m (ignored) on residential.
  // Highway's changed with rule 7's side route (doc/OBJECTS.md): a vehicle in scan 23 shows its
  // side alone, and its trailing end's place is seen empty; rule 4 carries it to scans 25-26
  // (+2,246 moving points, +117 false: recall 0.9938 -> 0.9970, precision 0.94040 -> 0.94044).
  // Highway's and residential's changed with the empty runs (DESIGN §2b): highway recall
  // 0.9970 -> 0.9972 (precision 0.9404 both); residential 69 points more moving, of a thing
  // 11-12 m away that its labels ignore. City's labels are unchanged.
  // Highway's changed with rule 4 backwards by the ends ("Its side comes and goes",
  // doc/OBJECTS.md): 96 points of scan 0, a mover on the opposite carriageway that the labels
  // miss (doc/BENCHMARK.md), carried back (precision 0.9404 -> 0.9403, recall the same).
  // Highway's and residential's changed with rule 2's previous scan's object (doc/OBJECTS.md):
  // a component rule 2 turns that is the object the previous scan moved whole goes with all of
  // its parts; highway 58 returns more moving in scan 20, none false (IoU 0.938011 -> 0.938089,
  // map AA the same); residential's dynamic.ply holds the same 1,716 points, 77 of them in
  // another order within their scan, its labels and maps the same.
  // Highway's and residential's changed with rule 6's feet "a ring away" (doc/OBJECTS.md): where
  // the ground cells around a foot hold too little road, the road is looked for out to where the
  // next ring down lands. Highway (images off) 5 moving returns more, 7 false (precision and
  // recall the same to four places); residential 3 returns 0.07-0.10 m over the road under a
  // true mover 27.6 m off, labelled static (precision 0.8244 -> 0.8220). City's are the same.
  expectDigest(highway, 0x9cd95e75d774eb96ull, 0x7d921aa399b9da6eull, 0xaa48c19967f04105ull,
               0xd9f89c85f32fdd56ull);
  expectDigest(residential, 0xe428832cc198d934ull, 0x7d3f0ba53e10b5c7ull, 0x488aeb63ef9ad154ull,
               0x8bf5900f18ddbfbdull);
}

TEST(Regression, TheRecordingCarsOwnReturnsLeaveLabelsAndMap) {
  // DESIGN §2.2, "Self returns": kitti_city's car drives at 7.6 m/s, and its roof and bonnet
  // return 20-40 points a scan 1.3-2.6 m from the sensor, which the windowed test flags. They are
  // labelled 0, the map removes them (map_labels 251, so no cleaned scan holds them), and none of
  // them is a labelled mover (the scores leave label 0 out: a mover taken here would be a hidden
  // miss).
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const std::string gt = test::dataDir() + "/kitti_city";
  const auto out = test::scratchDir("kitti_city_self");
  std::filesystem::remove_all(out);
  auto seq = io::KittiSequence::open(gt);
  const PipelineParams params;
  std::vector<std::vector<uint32_t>> self(seq.size());
  std::size_t counted = 0;
  {
    io::OutputWriter writer(out.string(), gt, params);
    LaserPipeline pl(params, [&](ScanResult&& r) {
      self[r.index] = r.self_index;
      counted += r.stats.self_returns;
      writer.write(r, std::nullopt);
    });
    for (std::size_t i = 0; i < seq.size(); ++i) pl.push(seq.frame(i));
    pl.finish();
    writer.finish(0.0, pl.freeSpace());
  }
  std::size_t total = 0, scans_with_roof = 0;
  for (std::size_t i = 0; i < seq.size(); ++i) {
    const Frame f = seq.frame(i);
    const Labels truth = seq.loadLabels(i, f.scan.original_size);
    const std::string stem = f.stem;
    const Labels labels = io::readLabels((out / "labels" / (stem + ".label")).string());
    const Labels map = io::readLabels((out / "map_labels" / (stem + ".label")).string());
    std::vector<float> range(f.scan.original_size, -1.0f), height(f.scan.original_size, 0.0f);
    for (std::size_t k = 0; k < f.scan.size(); ++k) {
      range[f.scan.originalIndex(k)] = f.scan.points[k].xyz().head<2>().norm();
      height[f.scan.originalIndex(k)] = f.scan.points[k].z;
    }
    scans_with_roof += self[i].size() >= 10;
    for (const uint32_t o : self[i]) {
      ASSERT_EQ(labels.at(o), kUnclassified) << "scan " << i << " point " << o;
      ASSERT_EQ(map.at(o), kMoving) << "scan " << i << " point " << o;
      // The car's body: 1-3 m off, 0.3-1.2 m below the sensor (1.73 m over the road).
      ASSERT_GT(range.at(o), 1.0f);
      ASSERT_LT(range.at(o), 3.0f);
      ASSERT_GT(height.at(o), -1.2f) << "scan " << i << " point " << o;
      ASSERT_LT(height.at(o), -0.3f) << "scan " << i << " point " << o;
      ASSERT_NE(gtClass(truth.at(o)), GtClass::kMoving) << "scan " << i << " point " << o;
    }
    total += self[i].size();
  }
  EXPECT_EQ(total, counted);
  EXPECT_GE(total, 400u);
  // Not in scans 8-10: the oncoming car passes within a voxel of the roof, which then joins its
  // component, and that reaches beyond the range.
  EXPECT_GE(scans_with_roof, 18u);
}

TEST(Regression, City) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const MosCounts c = runSet("kitti_city");  // measured: P 0.581, R 0.999 (bar: R 0.75, P 0.50)
  EXPECT_GE(c.recall(), 0.96);
  EXPECT_GE(c.precision(), 0.55);
}

TEST(Regression, Highway) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  std::vector<MosCounts> scans;
  const MosCounts c = runSet("kitti_highway", nullptr, PipelineParams{}, false, nullptr, &scans);
  // measured: P 0.940, R 0.997 (bar: R 0.75, P 0.50). Regression bounds: 0.890 before rule 4
  // held the tanker under static_fraction (doc/OBJECTS.md), 0.975 before it held objects through
  // the last K / 2 scans, 0.979 before it carried them back to the first K / 2.
  EXPECT_GE(c.recall(), 0.985);
  EXPECT_GE(c.precision(), 0.92);
  // The last K / 2 = 5 scans, too few after them to see a car leave: the VW ahead, receding at
  // 0.7-0.8 m/s, shows 3-9 of its 1,100 points moving in scans 27-29. Measured 0.990 (0.956
  // when it was lost there).
  MosCounts last;
  for (std::size_t i = scans.size() - 5; i < scans.size(); ++i) last += scans[i];
  EXPECT_GE(last.recall(), 0.975);
  EXPECT_GE(last.precision(), 0.95);
  // The first K / 2, too few before them to see a vehicle arrive: the truck 23 m and the car
  // 17 m behind, coming up on the sensor, show it only their fronts and were found from scan 4
  // on (none of their 2,300-2,600 returns a scan before). Measured 0.996 (0.925 before rule 4
  // at the start carried them back), precision 0.879 (0.871).
  MosCounts first;
  for (std::size_t i = 0; i < 5; ++i) first += scans[i];
  EXPECT_GE(first.recall(), 0.98);
  EXPECT_GE(first.precision(), 0.85);
}

TEST(Regression, ResidentialFalseAlarms) {
  CLEANMAP_REQUIRE_DATASET("kitti_residential");
  // measured: 0.029 % flagged, recall 0.985 (bar: 0.1 % flagged)
  const MosCounts c = runSet("kitti_residential");
  EXPECT_LE(c.flaggedRate(), 0.001);   // issue #3's bar
  EXPECT_LE(c.flaggedRate(), 0.0005);  // regression bound
  EXPECT_GE(c.recall(), 0.9);          // the motorcyclist
}

// A SLAM's keyframes 2.5 m apart: every third scan of the set, 0.3 s apart (doc/BENCHMARK.md,
// "A SLAM's keyframes further apart than sweeps"). The windowed test flags 11-35 % of a hedge's
// corner (12 x 14 m) from so far apart, and the object rules moved it whole, 8,447 false
// positives in the last scan: 9,593 in all, 0.83 % of the points flagged. Too wide for a vehicle
// (object.max_width, doc/OBJECTS.md rule 2) it keeps its points' labels: 2,041, 0.18 %.
TEST(Regression, ResidentialKeyframesEveryThirdScanMoveNoHedgeWhole) {
  CLEANMAP_REQUIRE_DATASET("kitti_residential");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_residential");
  constexpr std::size_t kEvery = 3;
  std::vector<MosCounts> scans((seq.size() + kEvery - 1) / kEvery);
  LaserPipeline pl(PipelineParams{}, [&](ScanResult&& r) {
    scans[r.index] = compareLabels(r.labels, seq.loadLabels(r.index * kEvery, r.labels.size()),
                                   "kitti_residential");
  });
  for (std::size_t i = 0; i < seq.size(); i += kEvery) {
    Frame f = seq.frame(i);
    f.index = i / kEvery;
    pl.push(std::move(f));
  }
  pl.finish();
  MosCounts all;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    all += scans[k];
    EXPECT_LT(scans[k].fp, 2000u) << "keyframe " << k;  // 8,499 in the last before
  }
  EXPECT_LE(all.flaggedRate(), 0.003);
  EXPECT_GE(all.recall(), 0.98);
}

// Issue #15's bars on the labelled sets decimated to 16 rings (default parameters): residential
// flags <= 0.2 % of its points, highway and city keep their recall within 0.05 of the 64-ring
// run's (0.975 and 0.999, Regression.Highway / City). Each of the four ways to keep every 4th
// laser is another 16-ring lidar of the same streets. Measured with the app (doc/BENCHMARK.md,
// "Sparse lidars vote through their rings"): residential 0.048 / 0.104 / 0.080 / 0.136 % flagged,
// highway recall 0.922 / 0.903 / 0.881 / 0.877, city 0.978 (offset 0); without the rings' vote
// 0.045 / 0.100 / 0.078 / 0.135 % and 0.870 / 0.883 / 0.862 / 0.863; before the edge rule
// (MovingTest::edgesOf) 0.13-0.37 % and highway 0.812-0.868. Here, before the ground's ceiling
// (DESIGN §2a): 0.034 / 0.082 / 0.056 / 0.106 % and 0.922 / 0.915 / 0.879 / 0.877; with it
// 0.044 / 0.088 / 0.075 / 0.155 % (the objects' sides that were ground are tested; at offset 3
// a post 3.6 m away turns moving whole in scans 3-5) and 0.918 / 0.910 / 0.889 / 0.884, the
// map's AA 55.4 -> 72.3 at offset 0. Rule 4 under static_fraction (doc/OBJECTS.md) holds the
// tanker there too: 0.950 / 0.943 / 0.943 / 0.936 (the 64-ring run 0.890 -> 0.975). Rule 4 at
// the start and arriving (sixtieth session) cost residential 0.062 / 0.099 / 0.092 / 0.156 % ->
// 0.067 / 0.103 / 0.130 / 0.171 %: small static objects a scan moved whole by mistake are carried
// back to the first scans or held one scan longer (doc/BENCHMARK.md, "Rule 4 arriving").
TEST(Regression, SixteenRingBars) {
  for (const char* set : {"kitti_city", "kitti_highway", "kitti_residential"})
    CLEANMAP_REQUIRE_DATASET(set);
  for (int offset = 0; offset < 4; ++offset) {
    const MosCounts r = runSetSixteenRings("kitti_residential", offset);
    EXPECT_LE(r.flaggedRate(), 0.002) << "lasers " << offset << " + 4k";
    EXPECT_LE(r.flaggedRate(), 0.0018) << "lasers " << offset << " + 4k";  // regression bound
    // Rule 4 backwards, "A slow seed" (doc/OBJECTS.md): at offset 0 a static object 27 m behind,
    // 1.2-1.8 m across as its rings come and go, is moved whole by mistake in scans 2-4; between
    // two of them its ends "moved" 0.10 m, then 0.05 m back. Seeded with that as its velocity,
    // it was carried back to scans 0-1 (30 false positives more). Over scans 2-4 its ends moved
    // 0.06 m, and scan 1 did not move it whole: no span, no track.
    if (offset == 0) EXPECT_LE(r.fp, 340u);  // measured 330 (360 seeded with any step of its ends)
    const MosCounts h = runSetSixteenRings("kitti_highway", offset);
    EXPECT_GE(h.recall(), 0.975 - 0.05) << "lasers " << offset << " + 4k";
    EXPECT_GE(h.precision(), 0.92) << "lasers " << offset << " + 4k";
    std::printf("  lasers %d + 4k: residential %.3f %% flagged, highway P %.3f R %.3f\n", offset,
                100.0 * r.flaggedRate(), h.precision(), h.recall());
  }
  const MosCounts c = runSetSixteenRings("kitti_city", 0);
  EXPECT_GE(c.recall(), 0.999 - 0.05);
  EXPECT_GE(c.precision(), 0.5);
  EXPECT_GE(c.precision(), 0.55);  // regression bound: measured 0.575
}

// DESIGN §2b "Coarse columns", §2d: the labelled sets with every other column, as an Ouster at
// 1024 columns would see them (0.35 degrees), default parameters. City's and highway's rings
// stand apart (0.52 degrees in their lower block) and the density is measured (0.37-0.43, scale
// 1 before the ninety-second session); residential's blur together (density 1, the rule off).
// Measured (ninety-second session): city P / R 0.599 / 0.999 (all columns 0.579 / 0.999;
// 0.591 with kColumnIsolated off), highway 0.942 / 0.988 (0.940 / 0.997; 0.941 off),
// residential 0.036 % flagged (0.029 %). Ninety-sixth session: the column links run here too
// (doc/OBJECTS.md rule 1, "Dense columns"); without their even spacing they joined a parked car
// 4.4 m to the left to the car passing it, which moved it for 12 scans (city precision 0.479).
TEST(Regression, EveryOtherColumnLikeAnOusterHoldsTheBars) {
  for (const char* set : {"kitti_city", "kitti_highway", "kitti_residential"})
    CLEANMAP_REQUIRE_DATASET(set);
  const MosCounts c = runSetEveryOtherColumn("kitti_city");
  const MosCounts h = runSetEveryOtherColumn("kitti_highway");
  const MosCounts r = runSetEveryOtherColumn("kitti_residential");
  std::printf(
      "  every other column: city P %.3f R %.3f, highway P %.3f R %.3f, residential %.3f "
      "%% flagged\n",
      c.precision(), c.recall(), h.precision(), h.recall(), 100.0 * r.flaggedRate());
  EXPECT_GE(c.recall(), 0.999 - 0.05);
  EXPECT_GE(c.precision(), 0.55);
  EXPECT_GE(h.recall(), 0.997 - 0.05);
  EXPECT_GE(h.precision(), 0.92);
  EXPECT_LE(r.flaggedRate(), 0.002);
}

// DESIGN §2.1, "Traffic that moves with the sensor": GICP on kitti_highway at 16 rings, where the
// traffic beside the crawling car outweighs the static scene. With registration.map_lag = 1 the
// relative error over 10 scans is 4.7 % / 3.2 % of the path (lasers 0 / 2 + 4k) and precision
// 0.946 / 0.939, against 27 % / 42 % and 0.859 / 0.733 with the default map_lag 0; given poses
// score 0.953 / 0.943 (doc/BENCHMARK.md, thirty-fourth session).
TEST(Regression, SixteenRingGicpWithMapLagHoldsInTraffic) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  PipelineParams p;
  p.poses = PoseSource::kGicp;
  p.registration.map_lag = 1;
  for (const int offset : {0, 2}) {
    std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> poses;
    const MosCounts h = runSetSixteenRings("kitti_highway", offset, p, &poses);
    ASSERT_EQ(poses.size(), 30u);
    const double err = test::relativeError(poses, 10);
    std::printf("  lasers %d + 4k, map_lag 1: 10-scan error %.1f %% of the path, P %.3f R %.3f\n",
                offset, 100.0 * err, h.precision(), h.recall());
    EXPECT_LE(err, 0.08) << "lasers " << offset << " + 4k";
    EXPECT_GE(h.precision(), 0.92) << "lasers " << offset << " + 4k";
    EXPECT_GE(h.recall(), 0.84) << "lasers " << offset << " + 4k";
  }
}

// DESIGN §2.1 step 4: a lidar that returns nothing for 0.8 s (scans 10-17 empty). Their poses
// are the motion model's guess, and the model goes on from them: with the velocity kept, the
// relative error over 10 scans is 0.6 / 1.7 / 1.8 % of the path (city / residential / highway)
// and GICP takes the scans after the gap up from there; when only accepted scans fed the model
// the guess stopped 5 scans in, 17.4 / 10.3 / 6.6 % (doc/BENCHMARK.md, thirty-fifth session).
// The labels score as a given-pose run with the same gap does, or better. On highway a tanker's
// share of moving points falls from 12 % to 3 % over scans 22-29; where it crossed rule 4's 10 %
// (scans 24-25, 0.027 of the set's recall a scan) moved with the poses' last centimetres (own /
// given recall 0.746 / 0.801, allowed 0.06) until rule 4 held it under 10 % where the scans after
// it see it leave (doc/OBJECTS.md): 0.911 / 0.914.
TEST(Regression, GicpKeepsTheVelocityThroughALidarDropout) {
  const auto gap = [](std::size_t i, Frame& f, Labels& truth) {
    if (i < 10 || i >= 18) return;
    f.scan.points.clear();
    f.scan.original_index.clear();
    f.scan.original_size = 0;
    f.scan.dropped_invalid = 0;
    truth.clear();
  };
  for (const char* set : {"kitti_city", "kitti_residential", "kitti_highway"}) {
    CLEANMAP_REQUIRE_DATASET(set);
    PipelineParams gicp;
    gicp.poses = PoseSource::kGicp;
    std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> poses;
    const MosCounts own = runSetEdited(set, gap, gicp, &poses), given = runSetEdited(set, gap);
    const double err = test::relativeError(poses, 10);
    std::printf("  %s: 10-scan error %.1f %% of the path; P %.3f R %.3f (given poses %.3f %.3f)\n",
                set, 100.0 * err, own.precision(), own.recall(), given.precision(), given.recall());
    EXPECT_LE(err, 0.04) << set;
    EXPECT_GE(own.precision(), given.precision() - 0.02) << set;
    EXPECT_GE(own.recall(), given.recall() - 0.02) << set;
  }
}

// Issue #11's bar: with its own poses (GICP odometry from the first given pose, default
// parameters) cleanmap's precision and recall are within 0.02 of the given-pose run's, or better.
// Measured (doc/BENCHMARK.md, Registration): city 0.581 / 0.999 against 0.581 / 0.999, highway
// 0.939 / 0.885 against 0.939 / 0.903 (laser only), residential 0.925 / 0.985 against
// 0.847 / 0.985; residential was 0.392 before the pose error widened the conflict check.
TEST(Regression, OwnPosesScoreAsGivenPoses) {
  for (const char* set : {"kitti_city", "kitti_highway", "kitti_residential"}) {
    CLEANMAP_REQUIRE_DATASET(set);
    PipelineParams gicp;
    gicp.poses = PoseSource::kGicp;
    const MosCounts own = runSet(set, nullptr, gicp), given = runSet(set);
    EXPECT_GE(own.precision(), given.precision() - 0.02) << set;
    const double tanker_scans = std::string(set) == "kitti_highway" ? 0.04 : 0.0;
    EXPECT_GE(own.recall(), given.recall() - 0.02 - tanker_scans) << set;
  }
}

// Issue #14 (DESIGN §3): on kitti_highway the camera may relabel only what the laser got wrong.
// Every truly static point it flags in view is a vehicle's edge or a roof line (doc/BENCHMARK.md,
// eighteenth session), so nothing is relabelled; with GICP's poses the near tanker, seen grazing,
// used to lose 6,308 points on a one-to-one vote (recall 0.885 -> 0.835), and with the grazing
// rule on, 58 (given) and 142 (GICP) of its points were still relabelled. Rule 4 holds the car
// 16 m ahead (0.6 m/s, along the line of sight) in scans 27-29; voted on there, 3 of its 9 cells
// looked changed and it lost 98 points in scan 27 (361 with the scans after): the camera leaves
// objects rule 4 holds to that decision (DESIGN §3).
TEST(Regression, HighwayCameraRelabelsNoMover) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  PipelineParams laser;
  laser.image.enabled = false;
  for (const PoseSource poses : {PoseSource::kGiven, PoseSource::kGicp}) {
    PipelineParams with = PipelineParams{}, without = laser;
    with.poses = without.poses = poses;
    std::size_t moved = 0;
    const MosCounts off = runSet("kitti_highway", nullptr, without);
    const MosCounts on = runSet("kitti_highway", nullptr, with, true, &moved);
    const char* name = poses == PoseSource::kGicp ? "gicp" : "given";
    EXPECT_GE(on.recall(), off.recall() - 0.005) << name;  // measured: equal
    EXPECT_LE(moved, 20u) << name;                         // measured: 0 and 0
  }
}

// Issue #16: with two threads a scan's beam index is built beside its crop, ground and camera
// view (LaserPipeline::prepare), the free space is inserted and the moving test runs on threads
// of their own; the labels, the maps and every figure of the camera check are those of one
// thread. The first 16 highway scans (K = 10: six decided with a full window), images on.
TEST(Regression, CameraRunIsTheSameWithOneOrTwoThreads) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  using Figures = std::vector<double>;
  const auto run = [&](int threads) {
    PipelineParams params;
    params.threads = threads;
    std::map<std::size_t, std::pair<uint64_t, Figures>> out;
    LaserPipeline pl(params, [&](ScanResult&& r) {
      OutputDigest d;
      d.add(r);
      const ScanStats& st = r.stats;
      out[r.index] = {
          d.labels ^ d.compact ^ d.full ^ d.moving,
          {double(st.image_scans), double(st.image_units), double(st.image_confirmed_colour),
           double(st.image_confirmed_depth), double(st.image_rejected_colour),
           double(st.image_rejected_depth), double(st.image_unseen), double(st.image_relabelled),
           double(st.image_held), double(st.image_links), double(st.image_links_aligned),
           st.image_link_shift}};
    });
    pl.setCamera(seq.camera());
    for (std::size_t i = 0; i < std::min<std::size_t>(seq.size(), 16); ++i) pl.push(seq.frame(i));
    pl.finish();
    return out;
  };
  const auto one = run(1), two = run(2);
  ASSERT_EQ(one.size(), two.size());
  std::size_t tested = 0;
  for (const auto& [index, r] : one) {
    EXPECT_EQ(r.first, two.at(index).first) << "scan " << index;
    EXPECT_EQ(r.second, two.at(index).second) << "scan " << index;
    tested += static_cast<std::size_t>(r.second[1]);
  }
  EXPECT_GT(tested, 50u);  // the camera check ran (199 objects over all 30 scans)
}

// Issue #16: with two threads the map's decision (OutputWriter::writeMaps) reads and groups the
// next scan beside this one's free-space lookup and objects; the map, its removals and every
// scan's map labels are those of one thread, byte for byte. kitti_city's first 14 scans.
TEST(Regression, CleanMapIsTheSameWithOneOrTwoThreads) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const std::string gt = test::dataDir() + "/kitti_city";
  auto seq = io::KittiSequence::open(gt);
  const auto dir = test::scratchDir("clean_map_threads");
  const auto run = [&](int threads) {
    PipelineParams params;
    params.threads = threads;
    const auto out = dir / ("threads" + std::to_string(threads));
    io::OutputOptions opts;
    opts.force = true;
    io::OutputWriter writer(out.string(), gt, params, opts);
    LaserPipeline pl(params, [&](ScanResult&& r) { writer.write(r, std::nullopt); });
    for (std::size_t i = 0; i < 14; ++i) pl.push(seq.frame(i));
    pl.finish();
    writer.finish(0.0, pl.freeSpace());
    return out;
  };
  const auto one = run(1), two = run(2);
  std::size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(one / "map_labels")) {
    const auto name = e.path().filename();
    EXPECT_TRUE(io::readTextFile(e.path().string()) ==
                io::readTextFile((two / "map_labels" / name).string()))
        << name << " differs";
    ++files;
  }
  EXPECT_EQ(files, 14u);
  for (const char* f : {"static_map_full.ply", "static_map.ply", "map_removed.ply"})
    EXPECT_TRUE(io::readTextFile((one / f).string()) == io::readTextFile((two / f).string()))
        << f << " differs";
  const auto report = nlohmann::json::parse(io::readTextFile((two / "report.json").string()));
  EXPECT_GT(report.at("map").at("objects_removed").get<int>(), 0);  // the objects decided some
}

// Issue #12's bar: the clean map's AA (ground truth within 50 m) strictly above DUFOMap's
// (RA-L 2024) on each labelled set: highway 85.0, city 98.5, residential 79.6. Measured:
// 98.23, 98.61, 94.19 (95.36, 98.52, 93.10 decided per voxel; doc/BENCHMARK.md).
TEST(Regression, CleanMapAboveDufomap) {
  for (const auto& [set, dufomap] :
       {std::pair{"kitti_highway", 0.850}, std::pair{"kitti_city", 0.985},
        std::pair{"kitti_residential", 0.796}}) {
    CLEANMAP_REQUIRE_DATASET(set);
    const MapScore m = cleanMapScore(set);
    RecordProperty(std::string(set) + "_AA", std::to_string(m.aa()));
    EXPECT_GT(m.aa(), dufomap) << set << ": SA " << m.sa() << ", DA " << m.da();
    EXPECT_GE(m.sa(), 0.96) << set;  // measured >= 0.971: the cleaning keeps the static world
  }
}

// Issue #16: GICP registering each frame on a thread of its own while the frames before it are
// decided (LaserPipeline::registerAhead, the app's way with threads > 1) gives every scan the same
// pose and labels as registering it in push(), images included, also when it is turned off and on
// again during the run; a pipeline holds at most K + 1 undecided frames; a clone taken while a
// frame registers continues as its original does.
TEST(Regression, RegisteringAheadChangesNothing) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  PipelineParams params;
  params.poses = PoseSource::kGicp;
  params.threads = 2;
  const std::size_t n = std::min<std::size_t>(seq.size(), 20), cut = 12;
  const std::size_t K = 10;                  // window_k auto: 1 s at KITTI's 10 Hz
  const std::size_t held = (K + 1) / 2 + 2;  // doc/OBJECTS.md rule 4 backwards
  using Results = std::map<std::size_t, std::pair<Eigen::Matrix4d, uint64_t>>;
  const auto into = [](Results& out) {
    return [&out](ScanResult&& r) {
      OutputDigest d;
      d.add(r);
      out[r.index] = {r.pose.matrix(), d.labels ^ d.full};
    };
  };
  Results inline_reg, ahead, copy, toggled;
  {
    LaserPipeline pl(params, into(inline_reg));
    pl.setCamera(seq.camera());
    for (std::size_t i = 0; i < n; ++i) pl.push(seq.frame(i));
    pl.finish();
  }
  {
    LaserPipeline pl(params, into(ahead));
    pl.setCamera(seq.camera());
    pl.registerAhead(true);
    std::unique_ptr<LaserPipeline> c;
    for (std::size_t i = 0; i < n; ++i) {
      pl.push(seq.frame(i));
      // Scan k is decided at push k + K + 1 (registering ahead) and handed on once `held` more
      // are decided; a run's first `held` stay held until 2 `held` are (doc/OBJECTS.md rule 4
      // backwards, "Held deeper at a run's start"). Pending: pushed, not handed on.
      const std::size_t decided = i > K ? i - K : 0;
      EXPECT_EQ(ahead.size(), decided > 2 * held ? decided - held : 0u) << i;
      EXPECT_EQ(pl.pending() + ahead.size(), i + 1) << i;
      if (i == cut) c = pl.clone(into(copy));
    }
    EXPECT_EQ(pl.windowK(), K);
    EXPECT_EQ(c->windowK(), K);
    for (std::size_t i = cut + 1; i < n; ++i) c->push(seq.frame(i));
    pl.finish();
    c->finish();
  }
  {
    LaserPipeline pl(params, into(toggled));
    pl.setCamera(seq.camera());
    for (std::size_t i = 0; i < n; ++i) {
      pl.registerAhead(i < 6 || i >= 9);  // off for three pushes, with a frame in flight
      pl.push(seq.frame(i));
    }
    pl.finish();
  }
  ASSERT_EQ(inline_reg.size(), n);
  ASSERT_EQ(ahead.size(), n);
  ASSERT_EQ(toggled.size(), n);
  for (const auto& [i, r] : inline_reg) {
    EXPECT_TRUE(ahead[i].first == r.first) << "pose of scan " << i;
    EXPECT_EQ(ahead[i].second, r.second) << "labels of scan " << i;
    EXPECT_TRUE(toggled[i].first == r.first) << "toggled: pose of scan " << i;
    EXPECT_EQ(toggled[i].second, r.second) << "toggled: labels of scan " << i;
  }
  // The scans not handed on at the cut: those decided after it, and the last `held` decided:
  // here all of them.
  ASSERT_LT(cut, K + 1 + held);
  ASSERT_EQ(copy.size(), n);
  for (const auto& [i, r] : copy) {
    EXPECT_TRUE(ahead[i].first == r.first) << "clone: pose of scan " << i;
    EXPECT_EQ(ahead[i].second, r.second) << "clone: labels of scan " << i;
  }
}

// DESIGN §2f: a long drive cut into chunks for a cluster. With epochs of 10 scans and K = 5 (so
// that the 30 scans hold two chunks), each chunk's owned scans get the whole run's labels byte
// for byte however far before its first owned epoch the chunk starts (2K at least), and the
// chunks' free-space accumulators, each fed only the scans it owns, merge into the whole run's.
// Without epochs (run.epoch 0) the duplicate filter and the persistence carry the overlap's
// different decisions into the owned scans: the chunk started at 3 labelled a whole car of scan
// 26 otherwise, and its free space differed.
TEST(Regression, ChunksReproduceTheWholeRun) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  PipelineParams p;
  p.ds.window_k = 5;
  p.epoch = 10;
  struct Run {
    std::map<long, Labels> labels;
    std::vector<Eigen::Vector3f> probes;  // every return and the midpoint of its beam
    std::unique_ptr<FreeSpaceMap> free;
  };
  auto run = [&](long first, long last, long own_first, long own_last) {
    Run out;
    LaserPipeline pl(p, [&](ScanResult&& r) {
      out.labels[static_cast<long>(r.index)] = r.labels;
      const Eigen::Vector3f o = r.pose.translation().cast<float>();
      for (const auto& q : r.static_full)
        out.probes.insert(out.probes.end(), {q.xyz(), 0.5f * (q.xyz() + o)});
      for (const auto& q : r.moving)
        out.probes.insert(out.probes.end(), {q.xyz(), 0.5f * (q.xyz() + o)});
    });
    pl.setMapScans(own_first, own_last);
    for (long i = first; i <= last; ++i) pl.push(seq.frame(static_cast<std::size_t>(i)));
    pl.finish();
    out.free = std::make_unique<FreeSpaceMap>(*pl.freeSpace());
    return out;
  };
  const long n = static_cast<long>(seq.size());
  ASSERT_EQ(n, 30);
  const Run whole = run(0, n - 1, 0, n - 1);
  // Chunk A owns 0..19: scans 20-23 may carry an object back to scan 19 (H + 1 = 4 with
  // H = ceil(K / 2), doc/OBJECTS.md rule 4 backwards) and their windows reach 28. Chunk B owns
  // 20..29: its start 3 lies 17 scans (>= 2K) before its first owned epoch; another start, 7,
  // must give the same.
  const Run a = run(0, 28, 0, 19);
  for (long s = 0; s < 20; ++s) EXPECT_TRUE(a.labels.at(s) == whole.labels.at(s)) << "scan " << s;
  for (const long start : {3L, 7L}) {
    const Run b = run(start, n - 1, 20, n - 1);
    for (long s = 20; s < n; ++s)
      EXPECT_TRUE(b.labels.at(s) == whole.labels.at(s)) << "start " << start << ", scan " << s;
    FreeSpaceMap merged(*b.free);
    merged.merge(*a.free);
    EXPECT_EQ(merged.voxelsMarked(), whole.free->voxelsMarked());
    EXPECT_EQ(merged.blocks(), whole.free->blocks());
    std::size_t differ = 0, free_probes = 0;
    for (const auto& q : whole.probes) {
      const FreeEvidence x = merged.evidence(q), y = whole.free->evidence(q);
      differ += x.count != y.count || x.hits != y.hits || x.first != y.first || x.last != y.last ||
                x.last_hit != y.last_hit || x.emptied_between != y.emptied_between;
      free_probes += y.count > 0;
    }
    EXPECT_EQ(differ, 0u) << "start " << start << ": voxels whose merged evidence differs";
    EXPECT_GT(free_probes, whole.probes.size() / 10);  // the probes do reach free space
  }
}
