// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §5 measures on tiny hand-made inputs with known answers; the map score against brute
// force; foreign .pcd / .ply maps; the summary table; bad inputs.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "cleanmap/core/map_score.h"
#include "cleanmap/eval/evaluate.h"
#include "cleanmap/eval/pictures.h"
#include "cleanmap/eval/roc.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/io/pcd.h"
#include "cleanmap/io/ply.h"
#include "cleanmap/pipeline/laser_pipeline.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

// A labelled sequence of 2 scans, sensor moving 1 m along x per scan. Each scan: a static wall
// (100 points, label 9), a moving car of 50 points inside the box of object 7 (label 251), and
// 10 ignored points (label 0). Truth and the world-frame points are returned for checking.
struct Tiny {
  fs::path dir;
  std::vector<std::vector<PointXYZI>> scans;
  std::vector<Labels> truth;
};

Tiny makeTiny(const std::string& name) {
  Tiny t;
  t.dir = test::scratchDir(name);
  std::string poses, times;
  for (int s = 0; s < 2; ++s) {
    std::vector<PointXYZI> pts;
    Labels l;
    for (int i = 0; i < 100; ++i) {  // wall at x = 10 (sensor frame), 0.1 m apart
      pts.push_back({10.f, -5.f + 0.1f * float(i), 0.5f, 0.f});
      l.push_back(9);
    }
    for (int i = 0; i < 50; ++i) {  // car around (5, 3, 0): a 5 x 10 grid on its side
      pts.push_back({4.f + 0.2f * float(i % 5), 3.f, -0.5f + 0.1f * float(i / 5), 0.f});
      l.push_back(251);
    }
    for (int i = 0; i < 10; ++i) {
      pts.push_back({-3.f, float(i), 0.f, 0.f});
      l.push_back(0);
    }
    char name6[16];
    std::snprintf(name6, sizeof name6, "%06d", s);
    io::writeKittiBin((t.dir / "velodyne" / (std::string(name6) + ".bin")).string(), pts);
    io::writeLabels((t.dir / "labels" / (std::string(name6) + ".label")).string(), l);
    poses += "1 0 0 " + std::to_string(s) + " 0 1 0 0 0 0 1 0\n";
    times += std::to_string(0.1 * s) + "\n";
    t.scans.push_back(pts);
    t.truth.push_back(l);
  }
  test::writeText(t.dir / "poses.txt", poses);
  test::writeText(t.dir / "times.txt", times);
  test::writeText(t.dir / "calib.txt", "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  test::writeText(t.dir / "objects.json",
                  R"([{"id": 7, "name": "car", "class": "car", "frames": {
                 "0": {"center": [4.4, 3.0, -0.05], "size": [1.2, 0.4, 1.2], "yaw": 0.0, "moving": true, "n_points": 50},
                 "1": {"center": [4.4, 3.0, -0.05], "size": [1.2, 0.4, 1.2], "yaw": 0.0, "moving": true, "n_points": 50}}}])");
  return t;
}

// Writes predicted labels: truth with the first `wrong_moving` moving points labelled static and
// the first `wrong_static` static points labelled moving, in each scan.
fs::path predict(const Tiny& t, const std::string& name, int wrong_moving, int wrong_static) {
  const auto dir = t.dir.parent_path() / (t.dir.filename().string() + "_" + name);
  fs::remove_all(dir);
  for (std::size_t s = 0; s < t.truth.size(); ++s) {
    Labels p = t.truth[s];
    int wm = wrong_moving, ws = wrong_static;
    for (auto& x : p) {
      if (x == 251 && wm > 0)
        x = 9, --wm;
      else if (x == 9 && ws > 0)
        x = 251, --ws;
      else if (x == 0)
        x = 9;  // a tool labels everything; ignore labels must not count
    }
    char name6[16];
    std::snprintf(name6, sizeof name6, "%06d.label", int(s));
    io::writeLabels((dir / "labels" / name6).string(), p);
  }
  test::writeText(
      dir / "report.json",  // a finished run
      R"({"generator": "cleanmap", "scans": 2, "timing_per_scan": {"total": {"median_ms": 50, "p95_ms": 60}}})");
  return dir;
}

eval::EvalReport run(const Tiny& t, const fs::path& result,
                     const std::optional<std::string>& labels = {}) {
  return eval::evaluate(t.dir.string(), eval::ResultInput::fromPath(result.string(), labels), {});
}

}  // namespace

TEST(EvalPoints, PerfectResult) {
  const auto t = makeTiny("perfect");
  const auto r = run(t, predict(t, "p", 0, 0));
  ASSERT_TRUE(r.mos);
  EXPECT_EQ(r.mos->tp, 100u);
  EXPECT_EQ(r.mos->fp, 0u);
  EXPECT_EQ(r.mos->fn, 0u);
  EXPECT_EQ(r.mos->tn, 200u);
  EXPECT_EQ(r.mos->ignored, 20u);  // ignore labels excluded even though the result labels them
  EXPECT_DOUBLE_EQ(r.mos->precision(), 1.0);
  EXPECT_DOUBLE_EQ(r.mos->recall(), 1.0);
  EXPECT_DOUBLE_EQ(r.mos->iou(), 1.0);
}

TEST(EvalPoints, AllWrongResult) {
  const auto t = makeTiny("allwrong");
  const auto r = run(t, predict(t, "w", 50, 100));
  EXPECT_EQ(r.mos->tp, 0u);
  EXPECT_EQ(r.mos->fp, 200u);
  EXPECT_EQ(r.mos->fn, 100u);
  EXPECT_DOUBLE_EQ(r.mos->precision(), 0.0);
  EXPECT_DOUBLE_EQ(r.mos->recall(), 0.0);
  EXPECT_DOUBLE_EQ(r.mos->iou(), 0.0);
}

TEST(EvalPoints, KnownMixAndPerScanSum) {
  const auto t = makeTiny("mix");
  const auto r = run(t, predict(t, "m", 10, 20));  // per scan: TP 40, FN 10, FP 20, TN 80
  EXPECT_NEAR(r.mos->precision(), 80.0 / 120.0, 1e-12);
  EXPECT_NEAR(r.mos->recall(), 80.0 / 100.0, 1e-12);
  EXPECT_NEAR(r.mos->iou(), 80.0 / 140.0, 1e-12);
  ASSERT_EQ(r.per_scan.size(), 2u);
  EXPECT_EQ(r.per_scan[0].second.tp + r.per_scan[1].second.tp, r.mos->tp);
}

TEST(EvalPoints, EmptyMovingClassGivesZerosNotNaN) {
  const MosCounts c = compareLabels(Labels(5, 9), Labels(5, 9), "x");
  EXPECT_EQ(c.tn, 5u);
  EXPECT_EQ(c.precision(), 0.0);
  EXPECT_EQ(c.recall(), 0.0);
  EXPECT_EQ(c.iou(), 0.0);
  const MosCounts ign = compareLabels(Labels(4, 251), Labels{0, 1, 0, 1}, "x");
  EXPECT_EQ(ign.evaluated(), 0u);
  EXPECT_EQ(ign.ignored, 4u);
}

// --camera-fov: a 100 x 100 px camera looking along the lidar's x axis (f 100 px, centre 50):
// u = 50 - 10 y for the wall at x = 10, so its points with y > -5 are in view (99 of 100); the car
// (x 4-4.8, y 3) projects left of the image. Five wall points labelled moving per scan: the one
// at y = -5 is out of view, so 4 false positives per scan are scored, and no moving point.
TEST(EvalPoints, CameraFovScoresOnlyThePointsInTheImage) {
  const auto t = makeTiny("fov");
  test::writeText(t.dir / "calib.txt",
                  "P2: 100 0 50 0 0 100 50 0 0 0 1 0\nTr: 0 -1 0 0 0 0 -1 0 1 0 0 0\n");
  for (const char* stem : {"000000", "000001"})
    eval::writePng((t.dir / "image_2" / (std::string(stem) + ".png")).string(),
                   cv::Mat(100, 100, CV_8UC3, cv::Scalar(90, 90, 90)));
  const auto result = predict(t, "fov", 0, 5);
  eval::EvalOptions opt;
  opt.camera_fov = true;
  const auto r =
      eval::evaluate(t.dir.string(), eval::ResultInput::fromPath(result.string(), {}), opt);
  ASSERT_TRUE(r.mos);
  EXPECT_EQ(r.mos->fp, 8u);
  EXPECT_EQ(r.mos->tn, 2u * 95u);
  EXPECT_EQ(r.mos->tp + r.mos->fn, 0u);
  EXPECT_EQ(r.mos->ignored, 2u * (1u + 50u + 10u));
  EXPECT_TRUE(r.camera_fov);
  EXPECT_NE(eval::toJson(r).find("\"scored_points\": \"camera_fov\""), std::string::npos);
  // The whole scan without it: 10 false positives, the car's 100 moving points.
  const auto all = run(t, result);
  EXPECT_EQ(all.mos->fp, 10u);
  EXPECT_EQ(all.mos->tp, 100u);
  // A sequence without a camera: one clear error naming it.
  const auto no_cam = makeTiny("fov_no_camera");
  test::expectError(
      [&] {
        eval::evaluate(no_cam.dir.string(),
                       eval::ResultInput::fromPath(predict(no_cam, "p", 0, 0).string(), {}), opt);
      },
      no_cam.dir.string(), "--camera-fov needs the sequence's camera");
}

TEST(EvalObjects, GradesByFractionOfMovingPoints) {
  const auto t = makeTiny("objects");
  auto grade = [&](int wrong) {
    const auto r = run(t, predict(t, "o" + std::to_string(wrong), wrong, 0));
    EXPECT_TRUE(r.objects);
    EXPECT_EQ(r.objects->size(), 1u);
    EXPECT_EQ(r.objects->front().moving_points, 100u);
    return r.objects->front();
  };
  EXPECT_EQ(grade(2).grade(), ObjectGrade::kDetected);  // f = 0.96
  EXPECT_EQ(grade(25).grade(), ObjectGrade::kPartial);  // f = 0.5
  EXPECT_NEAR(grade(25).fraction(), 0.5, 1e-12);
  EXPECT_EQ(grade(48).grade(), ObjectGrade::kMissed);  // f = 0.04
  EXPECT_EQ(gradeObject(0.9), ObjectGrade::kDetected);
  EXPECT_EQ(gradeObject(0.1), ObjectGrade::kPartial);
  EXPECT_EQ(gradeObject(0.0999), ObjectGrade::kMissed);
}

TEST(MapScore, RadiusIndexMatchesBruteForce) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<Eigen::Vector3f> map(3000), queries(3000);
  for (auto& p : map) p = {u(rng), u(rng), 0.2f * u(rng)};
  for (auto& q : queries) q = {u(rng), u(rng), 0.2f * u(rng)};
  for (const double radius : {0.02, 0.05, 0.08}) {
    const RadiusIndex index(map, radius);
    std::size_t found = 0;
    for (const auto& q : queries) {
      bool brute = false;
      for (const auto& p : map) brute |= (p - q).squaredNorm() <= float(radius * radius);
      ASSERT_EQ(index.hasNeighbour(q), brute) << "radius " << radius;
      found += brute;
    }
    EXPECT_GT(found, 0u);
    EXPECT_LT(found, queries.size());  // both outcomes exercised
  }
}

// The hints change no answer: every query hinted 16 and 8 ahead, as evaluate() and the map cases
// do, among them points the index cannot hold (NaN, 1e30) and an index with no points.
TEST(MapScore, PrefetchHintsChangeNoAnswer) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<Eigen::Vector3f> map(2000), queries(2000);
  for (auto& p : map) p = {u(rng), u(rng), 0.2f * u(rng)};
  for (auto& q : queries) q = {u(rng), u(rng), 0.2f * u(rng)};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  queries[100] = {nan, 0.f, 0.f};
  queries[200] = {1e30f, 0.f, 0.f};
  const RadiusIndex index(map, 0.05), empty({}, 0.05);
  std::size_t found = 0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    for (const RadiusIndex* x : {&index, &empty})
      x->prefetchAhead(i, queries.size(), [&](std::size_t k) { return queries[k]; });
    bool brute = false;
    for (const auto& p : map) brute |= (p - queries[i]).squaredNorm() <= 0.05f * 0.05f;
    ASSERT_EQ(index.hasNeighbour(queries[i]), brute) << "query " << i;
    EXPECT_FALSE(empty.hasNeighbour(queries[i]));
    found += brute;
  }
  EXPECT_GT(found, 0u);
  EXPECT_LT(found, queries.size());
}

// Points on cell boundaries and at exactly the radius: map points on a lattice of spacing
// radius (cells are 2 radius), queries moved off them by fractions of the radius along the axes
// and diagonals, so every "which neighbour cell" decision is met at and beside its edge.
TEST(MapScore, RadiusIndexMatchesBruteForceAtCellEdges) {
  for (const double radius : {0.05, 0.1, 0.25}) {
    const auto r = static_cast<float>(radius);
    std::vector<Eigen::Vector3f> map;
    for (int i = -6; i <= 6; i += 3)
      for (int j = -6; j <= 6; j += 3)
        for (int k = -4; k <= 4; k += 4) map.emplace_back(float(i) * r, float(j) * r, float(k) * r);
    const RadiusIndex index(map, radius);
    std::size_t found = 0, queries = 0;
    for (const Eigen::Vector3f& m : map)
      for (const float step : {0.0f, 0.5f, 0.9999f, 1.0f, 1.0001f, 1.5f, 2.0f})
        for (const Eigen::Vector3f& dir :
             {Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(0, -1, 0), Eigen::Vector3f(0, 0, 1),
              Eigen::Vector3f(-1, 1, 0).normalized(), Eigen::Vector3f(1, 1, 1).normalized()}) {
          const Eigen::Vector3f q = m + step * r * dir;
          bool brute = false;
          for (const auto& p : map) brute |= (p - q).squaredNorm() <= float(radius * radius);
          ASSERT_EQ(index.hasNeighbour(q), brute)
              << "radius " << radius << ", query " << q.transpose();
          found += brute;
          ++queries;
        }
    EXPECT_GT(found, 0u);
    EXPECT_LT(found, queries);
  }
}

TEST(MapScore, ScoresAgainstBruteForceAndFormulas) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.f, 4.f);
  std::vector<Eigen::Vector3f> map(2000), gt(4000);
  for (auto& p : map) p = {u(rng), u(rng), u(rng) * 0.1f};
  for (auto& p : gt) p = {u(rng), u(rng), u(rng) * 0.1f};
  const RadiusIndex index(map, 0.05);
  MapScorer scorer(index);
  MapScore brute;
  for (std::size_t i = 0; i < gt.size(); ++i) {
    const bool moving = i % 3 == 0;
    scorer.add(gt[i], moving);
    bool near = false;
    for (const auto& p : map) near |= (p - gt[i]).norm() <= 0.05f;
    (moving ? brute.moving_total : brute.static_total) += 1;
    if (moving && !near) ++brute.moving_removed;
    if (!moving && near) ++brute.static_kept;
  }
  const MapScore& s = scorer.score();
  EXPECT_EQ(s.static_kept, brute.static_kept);
  EXPECT_EQ(s.moving_removed, brute.moving_removed);
  EXPECT_NEAR(s.aa(), std::sqrt(s.sa() * s.da()), 1e-12);
  EXPECT_NEAR(s.ha(), 2 * s.sa() * s.da() / (s.sa() + s.da()), 1e-12);
  MapScore zero;
  EXPECT_EQ(zero.ha(), 0.0);
}

TEST(EvalMap, PerfectCleanMapScoresOne) {
  // The map = every static ground-truth point in the world: SA = DA = 1; adding the moving
  // points makes DA = 0. Also read back as .pcd (binary and ASCII): the same scores.
  const auto t = makeTiny("map");
  std::vector<PointXYZI> clean, dirty;
  for (std::size_t s = 0; s < t.scans.size(); ++s)
    for (std::size_t i = 0; i < t.scans[s].size(); ++i) {
      PointXYZI w = t.scans[s][i];
      w.x += float(s);  // pose: 1 m along x per scan
      if (t.truth[s][i] == 9) clean.push_back(w);
      if (t.truth[s][i] != 0) dirty.push_back(w);
    }
  const fs::path d = t.dir.parent_path();
  io::writePly((d / "clean.ply").string(), clean);
  io::writePcd((d / "clean.pcd").string(), clean);
  io::writePcd((d / "clean_ascii.pcd").string(), clean, true);
  io::writePly((d / "dirty.ply").string(), dirty);
  for (const char* f : {"clean.ply", "clean.pcd", "clean_ascii.pcd"}) {
    const auto r = run(t, d / f);
    ASSERT_TRUE(r.map) << f;
    EXPECT_FALSE(r.mos);
    EXPECT_EQ(r.map->static_total, 200u) << f;
    EXPECT_DOUBLE_EQ(r.map->sa(), 1.0) << f;
    EXPECT_DOUBLE_EQ(r.map->da(), 1.0) << f;
    EXPECT_DOUBLE_EQ(r.map->ha(), 1.0) << f;
  }
  const auto r = run(t, d / "dirty.ply");
  EXPECT_DOUBLE_EQ(r.map->sa(), 1.0);
  EXPECT_DOUBLE_EQ(r.map->da(), 0.0);
  EXPECT_DOUBLE_EQ(r.map->aa(), 0.0);
}

TEST(EvalMap, CropLimitsTheGroundTruthUnion) {
  const auto t = makeTiny("crop");
  io::writePly((t.dir.parent_path() / "one.ply").string(), {{0.f, 0.f, 0.f, 0.f}});
  eval::EvalOptions o;
  o.crop_tau = 6.0;  // leaves out the wall at x = 10
  const auto r = eval::evaluate(
      t.dir.string(), eval::ResultInput::fromPath((t.dir.parent_path() / "one.ply").string(), {}),
      o);
  EXPECT_EQ(r.map->static_total, 0u);
  EXPECT_EQ(r.map->moving_total, 100u);
}

// The map scorer against a brute-force one (every GT point against every map point) on a random
// sequence with rotated poses and points on both sides of the 50 m map range.
TEST(EvalMap, MatchesBruteForceWithinTheMapRange) {
  const auto dir = test::scratchDir("bruteforce");
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-70.f, 70.f), uz(-2.f, 3.f), jitter(-0.08f, 0.08f);
  std::string poses, times;
  std::vector<Eigen::Vector3f> map;
  std::vector<std::pair<Eigen::Vector3f, int>> gt;  // world point, 0 static / 1 moving
  std::vector<Eigen::Vector3f> gt_sensor;
  for (int s = 0; s < 3; ++s) {
    const Eigen::Isometry3d pose = Eigen::Translation3d(3.0 * s, -s, 0.1 * s) *
                                   Eigen::AngleAxisd(0.4 * s, Eigen::Vector3d::UnitZ());
    std::vector<PointXYZI> pts;
    Labels l;
    for (int i = 0; i < 600; ++i) {
      const PointXYZI p{u(rng), u(rng), uz(rng), 0.f};
      const uint32_t label = i % 7 == 0 ? 0u : (i % 3 == 0 ? 251u : 9u);
      pts.push_back(p);
      l.push_back(label);
      const Eigen::Vector3f w = pose.cast<float>() * p.xyz();
      // The map holds about half the points, some within 0.05 m, some just beyond.
      if (i % 2 == 0) map.push_back(w + Eigen::Vector3f(jitter(rng), jitter(rng), 0.f));
      if (label != 0) {
        gt.emplace_back(w, label == 251 ? 1 : 0);
        gt_sensor.push_back(p.xyz());
      }
    }
    char stem[16];
    std::snprintf(stem, sizeof stem, "%06d", s);
    io::writeKittiBin((dir / "velodyne" / (std::string(stem) + ".bin")).string(), pts);
    io::writeLabels((dir / "labels" / (std::string(stem) + ".label")).string(), l);
    const Eigen::Matrix4d m = pose.matrix();
    char row[512];
    std::snprintf(row, sizeof row,
                  "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                  m(0, 0), m(0, 1), m(0, 2), m(0, 3), m(1, 0), m(1, 1), m(1, 2), m(1, 3), m(2, 0),
                  m(2, 1), m(2, 2), m(2, 3));
    poses += row;
    times += std::to_string(0.1 * s) + "\n";
  }
  test::writeText(dir / "poses.txt", poses);
  test::writeText(dir / "times.txt", times);
  test::writeText(dir / "calib.txt", "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  std::vector<PointXYZI> cloud;
  for (const auto& q : map) cloud.push_back({q.x(), q.y(), q.z(), 0.f});
  const auto ply = dir.parent_path() / "bruteforce_map.ply";
  io::writePly(ply.string(), cloud);

  for (const double range : {50.0, 0.0, 20.0}) {
    MapScore brute;
    for (std::size_t i = 0; i < gt.size(); ++i) {
      const auto& p = gt_sensor[i];
      if (range > 0 && std::hypot(double(p.x()), double(p.y())) > range) continue;
      bool kept = false;
      for (const auto& q : map) kept = kept || (q - gt[i].first).norm() <= 0.05f;
      if (gt[i].second) {
        ++brute.moving_total;
        brute.moving_removed += !kept;
      } else {
        ++brute.static_total;
        brute.static_kept += kept;
      }
    }
    eval::EvalOptions o;
    o.map_range = range;
    const auto r = eval::evaluate(dir.string(), eval::ResultInput::fromPath(ply.string(), {}), o);
    ASSERT_TRUE(r.map);
    EXPECT_EQ(r.map->static_total, brute.static_total) << range;
    EXPECT_EQ(r.map->static_kept, brute.static_kept) << range;
    EXPECT_EQ(r.map->moving_total, brute.moving_total) << range;
    EXPECT_EQ(r.map->moving_removed, brute.moving_removed) << range;
    EXPECT_GT(brute.static_kept, 0u);
    EXPECT_LT(brute.static_kept, brute.static_total);
  }
}

TEST(EvalMap, RunCropNeedsTheRunsParameters) {
  const auto t = makeTiny("runcrop");
  io::writePly((t.dir.parent_path() / "runcrop.ply").string(), {{0.f, 0.f, 0.f, 0.f}});
  eval::EvalOptions o;
  o.run_crop = true;
  try {
    eval::evaluate(t.dir.string(),
                   eval::ResultInput::fromPath((t.dir.parent_path() / "runcrop.ply").string(), {}),
                   o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("params.ini"), std::string::npos) << e.what();
  }
}

TEST(Pcd, ReadsForeignLayouts) {
  const auto d = test::scratchDir("pcd");
  // ASCII with an extra rgb field and a NaN point of an organized cloud.
  test::writeText(
      d / "a.pcd",
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
      "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3 255\nnan nan nan "
      "0\n4 5 6 7\n");
  auto a = io::readPcd((d / "a.pcd").string());
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a[1].x, 4.f);
  EXPECT_EQ(a[1].z, 6.f);
  // binary with doubles and an intensity after a padding field
  {
    std::ofstream f(d / "b.pcd", std::ios::binary);
    f << "VERSION 0.7\nFIELDS x y z _ intensity\nSIZE 8 8 8 1 4\nTYPE F F F U F\nCOUNT 1 1 1 3 1\n"
         "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
    for (int i = 0; i < 2; ++i) {
      const double xyz[3] = {1.5 + i, -2.5, 0.25};
      const char pad[3] = {0, 0, 0};
      const float in = 0.5f * float(i);
      f.write(reinterpret_cast<const char*>(xyz), 24);
      f.write(pad, 3);
      f.write(reinterpret_cast<const char*>(&in), 4);
    }
  }
  auto b = io::readPcd((d / "b.pcd").string());
  ASSERT_EQ(b.size(), 2u);
  EXPECT_EQ(b[1].x, 2.5f);
  EXPECT_EQ(b[1].y, -2.5f);
  EXPECT_EQ(b[1].intensity, 0.5f);
  // binary_compressed (LZF), field-major: x x y y z z for 2 points of F4; the stream has a
  // literal run and a back reference (the repeated z values).
  {
    const float xs[2] = {1.f, 2.f}, ys[2] = {3.f, 4.f}, zs[2] = {7.f, 7.f};
    std::string raw;
    raw.append(reinterpret_cast<const char*>(xs), 8).append(reinterpret_cast<const char*>(ys), 8);
    raw.append(reinterpret_cast<const char*>(zs), 8);
    std::string lzf;
    lzf.push_back(char(19));  // literal run of 20 bytes: x, y, first z
    lzf.append(raw, 0, 20);
    lzf.push_back(char((2 << 5) | 0));  // back reference: length 2 + 2 = 4, distance 4
    lzf.push_back(char(3));
    std::ofstream f(d / "c.pcd", std::ios::binary);
    f << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT "
         "1\nPOINTS 2\n"
         "DATA binary_compressed\n";
    const uint32_t cs = uint32_t(lzf.size()), us = uint32_t(raw.size());
    f.write(reinterpret_cast<const char*>(&cs), 4).write(reinterpret_cast<const char*>(&us), 4)
        << lzf;
  }
  auto c = io::readPcd((d / "c.pcd").string());
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].x, 1.f);
  EXPECT_EQ(c[1].y, 4.f);
  EXPECT_EQ(c[1].z, 7.f);
}

TEST(Pcd, BadFilesAreClearErrors) {
  const auto d = test::scratchDir("pcdbad");
  test::writeText(d / "trunc.pcd",
                  "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 10\n"
                  "HEIGHT 1\nPOINTS 10\nDATA binary\nabc");
  test::expectError([&] { io::readPcd((d / "trunc.pcd").string()); }, "trunc.pcd", "truncated");
  test::writeText(d / "noxyz.pcd",
                  "VERSION 0.7\nFIELDS a b\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nPOINTS 0\nDATA ascii\n");
  test::expectError([&] { io::readPcd((d / "noxyz.pcd").string()); }, "noxyz.pcd", "no x, y, z");
  test::writeText(d / "map.xyz", "1 2 3\n");
  test::expectError([&] { io::readCloud((d / "map.xyz").string()); }, "map.xyz",
                    "unknown point-cloud format");
  test::expectError([&] { io::readPcd((d / "missing.pcd").string()); }, "missing.pcd",
                    "cannot open");
}

TEST(EvalErrors, BadInputsNameTheFile) {
  const auto t = makeTiny("errors");
  test::expectError([&] { eval::ResultInput::fromPath((t.dir / "nope").string(), {}); }, "nope",
                    "no such result");
  // A folder that is no finished cleanmap run: empty, or labels without report.json (a run that
  // was interrupted), is refused.
  const auto empty = t.dir.parent_path() / "errors_empty";
  fs::create_directories(empty);
  test::expectError([&] { eval::ResultInput::fromPath(empty.string(), {}); }, "errors_empty",
                    "no cleanmap report.json");
  const auto unfinished = predict(t, "unfinished", 0, 0);
  fs::remove(unfinished / "report.json");
  test::expectError([&] { run(t, unfinished); }, "errors_unfinished",
                    "not a finished cleanmap run");
  // A finished run with nothing to score.
  const auto nothing = t.dir.parent_path() / "errors_nothing";
  test::writeText(nothing / "report.json", R"({"generator": "cleanmap"})");
  test::expectError([&] { eval::ResultInput::fromPath(nothing.string(), {}); }, "errors_nothing",
                    "nothing to score");
  // Label file with the wrong count.
  const auto p = predict(t, "short", 0, 0);
  io::writeLabels((p / "labels/000001.label").string(), Labels(3, 9));
  test::expectError([&] { run(t, p); }, "000001.label", "160");
  // Ground truth without labels.
  fs::remove_all(t.dir / "labels");
  test::expectError([&] { run(t, predict(makeTiny("errors2"), "x", 0, 0)); }, "errors", "");
  test::expectError(
      [&] { eval::evaluate(t.dir.string(), eval::ResultInput::fromPath(p.string(), {}), {}); },
      t.dir.string(), "no labels");
}

TEST(EvalReport, JsonKeysSummaryAndPictures) {
  const auto t = makeTiny("report");
  const auto p = predict(t, "r", 10, 20);
  std::vector<PointXYZI> clean;
  for (const auto& q : t.scans[0]) clean.push_back(q);
  io::writePly((p / "static_map_full.ply").string(), clean);
  eval::EvalOptions o;
  o.pictures_dir = (p / "report").string();
  const auto r = eval::evaluate(t.dir.string(), eval::ResultInput::fromPath(p.string(), {}), o);
  eval::writeReport(o.pictures_dir, r);
  const auto j = nlohmann::json::parse(io::readTextFile(o.pictures_dir + "/report.json"));
  for (const char* k : {"precision", "recall", "iou", "SA", "DA", "AA", "HA"})
    EXPECT_TRUE(j.contains(k)) << k;
  EXPECT_NEAR(j["recall"].get<double>(), 0.8, 1e-12);
  EXPECT_TRUE(fs::file_size(o.pictures_dir + "/bev_000000.png") > 1000);
  EXPECT_TRUE(fs::file_size(o.pictures_dir + "/map_overview.png") > 1000);
  EXPECT_TRUE(fs::exists(o.pictures_dir + "/report.md"));
  // Summary over two copies: the overall row sums the counts, so the ratios are unchanged.
  const auto table =
      eval::summaryTable({o.pictures_dir + "/report.json", o.pictures_dir + "/report.json"});
  EXPECT_NE(table.find("| **all (summed counts)** | 4 | 0.667 | 0.800 | 0.571 |"),
            std::string::npos)
      << table;
  test::writeText(p / "bad.json", "{\"x\": 1}");
  test::expectError([&] { eval::summaryTable({(p / "bad.json").string()}); }, "bad.json",
                    "not an evaluation report");
}

TEST(EvalPictures, OutcomeColoursFollowTheLabels) {
  EXPECT_EQ(eval::outcome(251, 251), eval::Outcome::kTruePositive);
  EXPECT_EQ(eval::outcome(251, 9), eval::Outcome::kFalsePositive);
  EXPECT_EQ(eval::outcome(40, 252), eval::Outcome::kFalseNegative);
  EXPECT_EQ(eval::outcome(9, 40), eval::Outcome::kTrueNegative);
  EXPECT_EQ(eval::outcome(0, 251), eval::Outcome::kNotScored);
  EXPECT_EQ(eval::outcome(251, 0), eval::Outcome::kNotScored);
  const cv::Mat img = eval::birdsEyeView({{1.f, 0.f, 0.f, 0.f}}, {251}, {251}, 5.0, "t");
  // x forward is up: the TP point 1 m ahead is drawn 10 px above the centre, in red.
  const cv::Vec3b px = img.at<cv::Vec3b>(28 + 50 - 10 - 1 + 1, 50);
  EXPECT_GT(px[2], 200);
  EXPECT_LT(px[0], 100);
}

TEST(Roc, SweepMatchesADirectRunAtEachSetting) {
  CLEANMAP_REQUIRE_DATASET("kitti_city");
  const std::string gt = test::dataDir() + "/kitti_city";
  PipelineParams base;
  base.ds.window_k = 2;  // small window: a quick test
  eval::RocOptions o;
  o.sigma_r = {0.10, 0.45};
  o.lambda_theta = {0.0035};
  o.first = 8;
  o.last = 12;
  const auto res = eval::rocSweep(gt, base, o);
  ASSERT_EQ(res.size(), 2u);
  for (const auto& s : res) {
    PipelineParams p = base;
    p.ds.sigma_r = s.sigma_r;
    MosCounts direct;
    auto seq = io::KittiSequence::open(gt);
    LaserPipeline pipe(p, [&](ScanResult&& r) {
      direct += compareLabels(r.labels, seq.loadLabels(r.index, r.labels.size()), "x");
    });
    for (std::size_t i = 8; i <= 12; ++i) pipe.push(seq.frame(i));
    pipe.finish();
    EXPECT_EQ(s.counts.tp, direct.tp);
    EXPECT_EQ(s.counts.fp, direct.fp);
    EXPECT_GE(s.tpr(), 0.0);
    EXPECT_LE(s.fpr(), 1.0);
  }
  const auto d = test::scratchDir("roc");
  eval::writeRoc(d.string(), "kitti_city", res, base);
  EXPECT_TRUE(fs::file_size(d / "roc.png") > 1000);
  EXPECT_NE(io::readTextFile((d / "roc.md").string()).find("| 0.0035 |"), std::string::npos);
}
