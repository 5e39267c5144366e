// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-sim (issue #4): scenario parsing, exact ray-cast geometry, determinism, the written
// folder read back by our KITTI reader, the camera seeing what the lidar sees.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "cleanmap/io/kitti.h"
#include "cleanmap/io/objects.h"
#include "cleanmap/sim/generate.h"
#include "cleanmap/sim/world.h"
#include "test_data.h"

using namespace cleanmap;
namespace fs = std::filesystem;

namespace {

// One box 10 m ahead of a sensor at the origin, no noise, no dropout.
sim::Scenario boxAhead() {
  return sim::parseScenario(R"(
[scenario]
frames = 2
[sensor]
range_noise = 0
dropout = 0
camera = false
[ego]
path = 0 0  100 0
speed = 0
[box]
center = 12 0
size = 4 6 3
[mover]
name = m
path = 0 8  100 8
speed = 3
)",
                            "box_ahead");
}

}  // namespace

TEST(SimScenario, DefaultScenarioParsesAndHasTheHardCasesOfItsKind) {
  const auto sc = sim::defaultScenario();
  EXPECT_EQ(sc.frames, 40);
  EXPECT_GE(sc.movers.size(), 3u);
  EXPECT_TRUE(sc.sensor.camera);
}

TEST(SimScenario, ShippedScenariosParse) {
  const fs::path dir = fs::path(CLEANMAP_SOURCE_DIR) / "datasets/scenarios";
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".ini") {
      EXPECT_NO_THROW(sim::loadScenario(e.path().string())) << e.path();
      ++n;
    }
  EXPECT_GE(n, 8);
}

TEST(SimScenario, BadFilesAreOneLineErrorsWithTheLine) {
  test::expectError([] { sim::parseScenario("[scenario]\nframes = ten\n", "s.ini"); }, "s.ini:2",
                    "not a number");
  test::expectError([] { sim::parseScenario("[boat]\n", "s.ini"); }, "s.ini:1", "unknown section");
  test::expectError([] { sim::parseScenario("[box]\ncolor = 1 0 0\n", "s.ini"); }, "s.ini:2",
                    "unknown key 'color'");
  test::expectError([] { sim::parseScenario("[box]\nsize = 1 -2 3\n", "s.ini"); }, "s.ini:2",
                    "must be > 0");
  test::expectError([] { sim::parseScenario("[mover]\nspeed = 3\n", "s.ini"); }, "s.ini",
                    "no path");
  test::expectError([] { sim::parseScenario("[ground]\nslope = 0.5\n", "s.ini"); }, "s.ini:2",
                    "slope = 0.5 is outside [-0.3, 0.3]");
  test::expectError([] { sim::parseScenario("[ego]\npose_drift = 0.5\n", "s.ini"); }, "s.ini:2",
                    "outside");
  test::expectError([] { sim::loadScenario("/nonexistent/x.ini"); }, "x.ini", "");
}

// Issue #15: the lidar is a preset or rings over a vertical field of view.
TEST(SimScenario, SensorModelsAndRingsParse) {
  auto sc = sim::parseScenario("[sensor]\nmodel = vlp16\n", "s.ini");
  ASSERT_EQ(sc.sensor.elevations.size(), 16u);
  EXPECT_NEAR(sc.sensor.elevations.front() * 180 / M_PI, 15.0, 1e-9);
  EXPECT_NEAR(sc.sensor.elevations.back() * 180 / M_PI, -15.0, 1e-9);
  EXPECT_DOUBLE_EQ(sc.sensor.azimuth_step_deg, 0.2);
  sc = sim::parseScenario("[sensor]\nvertical_fov_deg = -25 5\nrings = 31\n", "s.ini");
  ASSERT_EQ(sc.sensor.elevations.size(), 31u);
  EXPECT_NEAR(sc.sensor.elevations[1] * 180 / M_PI, 4.0, 1e-9);  // 1 degree apart
  EXPECT_DOUBLE_EQ(sc.sensor.azimuth_step_deg, 0.18);            // the HDL-64E's
  sc = sim::parseScenario("[sensor]\nmodel = os1-128\nrings = 64\nazimuth_step_deg = 0.5\n",
                          "s.ini");
  ASSERT_EQ(sc.sensor.elevations.size(), 64u);
  EXPECT_NEAR(sc.sensor.elevations.back() * 180 / M_PI, -22.5, 1e-9);
  EXPECT_DOUBLE_EQ(sc.sensor.azimuth_step_deg, 0.5);
  EXPECT_EQ(sim::defaultScenario().sensor.elevations, sim::hdl64Elevations());
  test::expectError([] { sim::parseScenario("[sensor]\nmodel = hdl65\n", "s.ini"); }, "s.ini:2",
                    "expected one of hdl64, hdl32, vlp16, os1-64, os1-128");
  test::expectError([] { sim::parseScenario("[sensor]\nrings = 16.5\n", "s.ini"); }, "s.ini:2",
                    "expected an integer");
  test::expectError([] { sim::parseScenario("[sensor]\nvertical_fov_deg = 5 -25\n", "s.ini"); },
                    "s.ini:2", "lo < hi");
}

TEST(SimLidar, ScansHaveTheRingsOfTheirModel) {
  for (const auto m : {SensorModel::kVlp16, SensorModel::kHdl32, SensorModel::kOs1_128}) {
    auto sc = sim::defaultScenario();
    sc.sensor.elevations = ringElevations(m);
    sc.sensor.range_noise = 0;
    const auto s = sim::simulateScan(sc, 0, 2);
    std::vector<double> el;  // degrees; rings are runs of elevations less than 0.05 deg apart
    for (const auto& p : s.points) el.push_back(std::atan2(p.z, std::hypot(p.x, p.y)) * 180 / M_PI);
    std::sort(el.begin(), el.end());
    int rings = el.empty() ? 0 : 1;
    for (std::size_t i = 1; i < el.size(); ++i) rings += el[i] - el[i - 1] > 0.05;
    EXPECT_EQ(rings, sensorPreset(m).rings) << sensorPreset(m).name;
  }
}

// DESIGN §2d: a sparse lidar's angular resolution is measured from its scan; the HDL-64E's rings
// blur together (0.33-0.5 degrees apart) and count as the reference density. An Ouster at 1024
// columns has rings as close (0.53, 0.35 degrees) but columns twice as coarse (0.35 degrees):
// it is measured, not taken for the reference (session 91 found the OS1-64 run at density 1,
// object.min_moving 20 for its 0.41).
TEST(SimLidar, ResolutionOfSparseLidarsIsMeasuredInTheScan) {
  auto sc = sim::defaultScenario();
  for (const auto m :
       {SensorModel::kVlp16, SensorModel::kHdl32, SensorModel::kOs1_64, SensorModel::kOs1_128}) {
    sc.sensor.elevations = ringElevations(m);
    sc.sensor.azimuth_step_deg = sensorPreset(m).azimuth_step_deg;
    const auto r = measureResolution(sim::simulateScan(sc, 5, 2).points);
    ASSERT_TRUE(r) << sensorPreset(m).name;
    const auto want = presetResolution(m);
    EXPECT_NEAR(r->vertical_deg, want.vertical_deg, 0.02) << sensorPreset(m).name;
    EXPECT_NEAR(r->azimuth_deg, want.azimuth_deg, 0.01) << sensorPreset(m).name;
    EXPECT_NEAR(densityScale(*r), densityScale(want), 0.03) << sensorPreset(m).name;
  }
  EXPECT_NEAR(densityScale(presetResolution(SensorModel::kVlp16)), 0.19, 0.01);
  EXPECT_NEAR(densityScale(presetResolution(SensorModel::kOs1_64)), 0.41, 0.01);
  EXPECT_NEAR(densityScale(presetResolution(SensorModel::kOs1_128)), 0.60, 0.01);
  EXPECT_DOUBLE_EQ(densityScale(presetResolution(SensorModel::kHdl64)), 1.0);
  sc.sensor.elevations = ringElevations(SensorModel::kHdl64);
  sc.sensor.azimuth_step_deg = 0.18;
  double rings = 0;
  EXPECT_FALSE(measureResolution(sim::simulateScan(sc, 5, 2).points, &rings));
  // Its rings' gap all the same, for its roofs (doc/OBJECTS.md rule 6): the upper block's 0.33.
  EXPECT_NEAR(rings, 10.33 / 31.0, 0.02);
  rings = -1;
  EXPECT_FALSE(measureResolution({}, &rings));
  EXPECT_EQ(rings, -1);  // nothing measured, nothing written
}

// DESIGN §2d: a point count tuned on the HDL-64E (object.min_moving, rule 7's least component of
// doc/OBJECTS.md) asks as many returns of another lidar as it returns from the same object: the
// same at the HDL-64E, 41 % at an OS1-64's 1024 columns, a fifth at a VLP-16, and never none
// (a count of 0 would pass any component).
TEST(SimLidar, AnHdl64CountScalesByEachLidarsDensityAndNeverToNone) {
  EXPECT_EQ(scaledCount(100, densityScale(presetResolution(SensorModel::kHdl64))), 100);
  EXPECT_NEAR(scaledCount(100, densityScale(presetResolution(SensorModel::kOs1_64))), 41, 1);
  EXPECT_NEAR(scaledCount(100, densityScale(presetResolution(SensorModel::kVlp16))), 19, 1);
  EXPECT_EQ(scaledCount(20, 0.05), 1);  // the least density densityScale gives
  EXPECT_EQ(scaledCount(1, 0.3), 1);
  int last = 0;
  for (const double d : {0.05, 0.19, 0.41, 0.6, 1.0, 2.0, 4.0}) {
    EXPECT_GE(scaledCount(20, d), last) << d;  // a denser lidar asks no fewer
    last = scaledCount(20, d);
  }
  EXPECT_EQ(last, 80);
}

// Every k-th laser of a KITTI HDL-64E scan.
std::vector<PointXYZI> keepEveryKthRing(const std::vector<PointXYZI>& pts, int k) {
  std::vector<PointXYZI> out;
  for (const std::size_t i : test::kittiRingsKept(pts, k)) out.push_back(pts[i]);
  return out;
}

// Issue #15: real 16-ring scans. KITTI's lasers sit at different heights on the head, so near
// returns of one laser spread over a degree of elevation and short runs of them fall between
// rings; the upper block (1/3 degree apart) blurs into one run. Every 4th laser is 1.33 (upper
// block) to 2 (lower) degrees from the next, at the HDL-64E's azimuth step: a quarter of its
// density. The whole scan stays the reference (not measured).
TEST(SimLidar, ResolutionOfRealScansDecimatedTo16RingsIsMeasured) {
  for (const char* set : {"kitti_city", "kitti_highway", "kitti_residential"}) {
    CLEANMAP_REQUIRE_DATASET(set);
    const auto seq = io::KittiSequence::open(test::dataDir() + "/" + set);
    for (const std::size_t f : {std::size_t(0), seq.size() / 2, seq.size() - 1}) {
      const auto pts = seq.loadScan(f).points;
      EXPECT_FALSE(measureResolution(pts)) << set << " scan " << f;
      const auto r = measureResolution(keepEveryKthRing(pts, 4));
      ASSERT_TRUE(r) << set << " scan " << f;
      EXPECT_GT(r->vertical_deg, 1.3) << set << " scan " << f;
      EXPECT_LT(r->vertical_deg, 2.1) << set << " scan " << f;
      EXPECT_NEAR(r->azimuth_deg, 0.17, 0.02) << set << " scan " << f;
      EXPECT_NEAR(densityScale(*r), 0.25, 0.07) << set << " scan " << f;
    }
  }
}

// DESIGN §2d: the same scans with every other column (0.35 degrees, an Ouster's at 1024 columns).
// City's and highway's lower blocks stand apart (0.5 degrees): measured, density 0.39-0.42 (0.5
// is the truth; the blocks' 0.52-degree gap stands for the 0.42 of the whole head). Residential's
// rings blur into fewer than 8 runs: not measured, the reference density, as its whole scans.
TEST(SimLidar, ResolutionOfRealScansWithEveryOtherColumnIsMeasured) {
  for (const char* set : {"kitti_city", "kitti_highway", "kitti_residential"}) {
    CLEANMAP_REQUIRE_DATASET(set);
    const auto seq = io::KittiSequence::open(test::dataDir() + "/" + set);
    for (const std::size_t f : {std::size_t(0), seq.size() / 2, seq.size() - 1}) {
      const auto pts = seq.loadScan(f).points;
      std::vector<PointXYZI> kept;
      for (const std::size_t i : test::kittiColumnsKept(pts, 2)) kept.push_back(pts[i]);
      const auto r = measureResolution(kept);
      if (std::string(set) == "kitti_residential") {
        EXPECT_FALSE(r) << set << " scan " << f;
        continue;
      }
      ASSERT_TRUE(r) << set << " scan " << f;
      EXPECT_NEAR(r->azimuth_deg, 0.35, 0.02) << set << " scan " << f;
      EXPECT_NEAR(densityScale(*r), 0.4, 0.05) << set << " scan " << f;
    }
  }
}

TEST(SimScenario, PoseDriftIsASeededRandomWalkOfTheRequestedSize) {
  auto sc = sim::parseScenario("[ego]\npath = 0 0  1000 0\nspeed = 10\n", "s.ini");
  for (int k : {0, 7, 30})
    EXPECT_TRUE(sim::reportedPose(sc, k).isApprox(sim::egoPose(sc, k / sc.rate_hz)));
  sc.ego_pose_drift = 0.01;  // 1 cm per frame (1 m travelled) and axis
  EXPECT_TRUE(sim::reportedPose(sc, 0).isApprox(sim::egoPose(sc, 0)));  // no distance, no error
  double sq = 0;
  const int n = 400;
  for (int k = 1; k <= n; ++k) {
    const Eigen::Isometry3d r = sim::reportedPose(sc, k), t = sim::egoPose(sc, k / sc.rate_hz);
    EXPECT_TRUE(r.linear().isApprox(t.linear()));
    EXPECT_NEAR(r.translation().z(), t.translation().z(), 1e-12);  // horizontal only
    const Eigen::Vector2d step = (r.translation() - t.translation()).head<2>() -
                                 (sim::reportedPose(sc, k - 1).translation() -
                                  sim::egoPose(sc, (k - 1) / sc.rate_hz).translation())
                                     .head<2>();
    sq += step.squaredNorm();
  }
  EXPECT_NEAR(std::sqrt(sq / (2 * n)), 0.01, 0.0015);  // per-axis sigma of a step
  EXPECT_TRUE(sim::reportedPose(sc, 50).isApprox(sim::reportedPose(sc, 50)));  // deterministic
  sc.seed = 2;
  EXPECT_FALSE(sim::reportedPose(sc, 50).isApprox(sim::reportedPose(
      sim::parseScenario("[ego]\npath = 0 0  1000 0\nspeed = 10\npose_drift = 0.01\n", "s.ini"),
      50)));
}

TEST(SimLidar, RangesAreExactOnABoxAndTheGround) {
  const auto sc = boxAhead();
  const auto s = sim::simulateScan(sc, 0, 2);
  ASSERT_GT(s.points.size(), 50000u);
  std::size_t box = 0, ground = 0;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    const auto& p = s.points[i];
    if (s.surface[i] == sim::Surface::kStatic && std::abs(p.y) < 2.5 && p.z > -1.0 && p.z < 1.0) {
      EXPECT_NEAR(p.x, 10.0, 1e-4);  // the box's near face, x = 12 - 2
      ++box;
    }
    if (s.surface[i] == sim::Surface::kGround) {
      EXPECT_NEAR(p.z, -sc.sensor.height, 1e-4);
      ++ground;
    }
  }
  EXPECT_GT(box, 500u);
  EXPECT_GT(ground, 10000u);
}

TEST(SimLidar, HasSixtyFourRingsAtHdl64Elevations) {
  const auto& e = sim::hdl64Elevations();
  ASSERT_EQ(e.size(), 64u);
  EXPECT_NEAR(e.front() * 180 / M_PI, 2.0, 1e-9);
  EXPECT_NEAR(e.back() * 180 / M_PI, -24.33, 1e-9);
  for (std::size_t i = 1; i < e.size(); ++i) EXPECT_LT(e[i], e[i - 1]);
}

TEST(SimLidar, DeterministicWhateverTheThreads) {
  auto sc = sim::defaultScenario();
  const auto a = sim::simulateScan(sc, 3, 1), b = sim::simulateScan(sc, 3, 2);
  ASSERT_EQ(a.points.size(), b.points.size());
  EXPECT_EQ(0, std::memcmp(a.points.data(), b.points.data(), a.points.size() * sizeof(PointXYZI)));
  EXPECT_EQ(a.labels, b.labels);
  sc.seed = 2;  // another seed: other noise
  const auto c = sim::simulateScan(sc, 3, 2);
  EXPECT_TRUE(c.points.size() != a.points.size() ||
              std::memcmp(a.points.data(), c.points.data(), a.points.size() * sizeof(PointXYZI)) !=
                  0);
}

TEST(SimLidar, MoverLabelsFollowItsMotion) {
  // Moving at 3 m/s: 251; waiting before its start, or stopped: 9; between 0.2 and 0.5 m in
  // +-0.5 s: ignore (0).
  auto sc = boxAhead();
  auto s = sim::simulateScan(sc, 0, 2);
  std::size_t moving = 0;
  for (std::size_t i = 0; i < s.labels.size(); ++i)
    if (s.surface[i] == sim::Surface::kMover) {
      EXPECT_EQ(s.labels[i], 251u);
      ++moving;
    } else {
      EXPECT_EQ(s.labels[i], std::hypot(s.points[i].x, s.points[i].y) > 50 ? 0u : 9u);
    }
  EXPECT_GT(moving, 100u);
  sc.movers[0].start = 10;  // still waiting at t = 0
  s = sim::simulateScan(sc, 0, 2);
  for (std::size_t i = 0; i < s.labels.size(); ++i) {
    if (s.surface[i] == sim::Surface::kMover) {
      EXPECT_EQ(s.labels[i], 9u);
    }
  }
  sc.movers[0].start = 0;
  sc.movers[0].speed = 0.35;  // 0.35 m in +-0.5 s: between the static and moving thresholds
  EXPECT_EQ(sim::World(sc, 2.0).solids().back().motion, -1);
  sc.movers[0].stop = std::make_pair(1.0, 3.0);  // standing still around t = 2
  EXPECT_EQ(sim::World(sc, 2.0).solids().back().motion, 0);
}

// `accel`: pulls away from rest and brakes to a stop at that rate (s = a t^2 / 2 up to speed),
// and the labels' +-0.5 s test follows it; without it the speed changes at once.
TEST(SimLidar, MoversAccelerateAndBrakeAtTheirRate) {
  sim::MoverSpec m;
  m.path = {{0, 0}, {1000, 0}};
  m.speed = 6;
  m.start = 2;
  m.stop = std::make_pair(10.0, 12.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 3), 6.0);  // at once
  m.accel = 2;                                 // 3 s to reach 6 m/s, 9 m on the way
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 1.5), 0.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 3), 1.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 5), 9.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 6), 15.0);
  // Brakes over the last 3 s before the stop at 10 s: 9 + 12 + 9 m, and stands still until 12.
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 9), 30.0 - 1.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 10), 30.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 11.5), 30.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 13), 31.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 16), 30.0 + 9.0 + 6.0);
  // A stretch too short to reach full speed: up for half of it, down for the other half.
  m.stop = std::make_pair(4.0, 12.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 3), 1.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 4), 2.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 8), 2.0);
  // A mover that does not wait is at speed from the first frame, and never before it.
  m.start = 0;
  m.stop.reset();
  EXPECT_DOUBLE_EQ(sim::moverArc(m, -0.05), 0.0);
  EXPECT_DOUBLE_EQ(sim::moverArc(m, 2), 12.0);

  // The labels: 0.5 s after pulling away at 2 m/s2 it has covered 0.25 m over +-0.5 s (ignore);
  // 1 s after, 1 m (moving). At full speed at once it is moving from 0.42 s before it pulls away.
  auto sc = boxAhead();
  sc.movers[0].speed = 6;
  sc.movers[0].start = 1;
  sc.movers[0].accel = 2;
  EXPECT_EQ(sim::World(sc, 1.0).solids().back().motion, -1);
  EXPECT_EQ(sim::World(sc, 1.5).solids().back().motion, 1);
  EXPECT_EQ(sim::World(sc, 0.6).solids().back().motion, 0);
  sc.movers[0].accel = 0;
  EXPECT_EQ(sim::World(sc, 0.55).solids().back().motion, -1);
  EXPECT_EQ(sim::World(sc, 0.6).solids().back().motion, 1);
  test::expectError([] { sim::parseScenario("[mover]\npath = 0 0  9 0\naccel = -1\n", "s.ini"); },
                    "s.ini:3", "outside");
  EXPECT_DOUBLE_EQ(
      sim::parseScenario("[mover]\npath = 0 0  9 0\naccel = 2.5\n", "s.ini").movers[0].accel, 2.5);
}

TEST(SimOutput, FolderReadsBackWithPosesLabelsObjectsAndCamera) {
  auto sc = sim::defaultScenario();
  sc.frames = 3;
  const auto dir = test::scratchDir("sim_out");
  const auto sum = sim::generateSequence(sc, dir.string(), {});
  EXPECT_EQ(sum.frames, 3u);
  EXPECT_EQ(sum.images, 3u);
  const auto seq = io::KittiSequence::open(dir.string());
  ASSERT_EQ(seq.size(), 3u);
  ASSERT_TRUE(seq.hasLabels() && seq.hasImages() && seq.hasPoses() && seq.camera());
  for (int k = 0; k < 3; ++k) {
    const auto truth = sim::egoPose(sc, k / sc.rate_hz);
    EXPECT_LT((seq.poses()[k].translation() - truth.translation()).norm(), 1e-6);
    EXPECT_LT((seq.poses()[k].linear() - truth.linear()).norm(), 1e-6);
    const Scan s = seq.loadScan(k);
    const auto direct = sim::simulateScan(sc, k, 2);
    ASSERT_EQ(s.size(), direct.points.size());
    EXPECT_EQ(seq.loadLabels(k, s.original_size), direct.labels);
  }
  const auto objects = io::readObjects(*seq.objectsPath());
  EXPECT_GE(objects.size(), 4u);
  // The camera sees the parked blue car where the lidar sees it: project the lidar points of
  // parked_1 and compare the pixel colours with its colour (0.2, 0.3, 0.7: blue dominant).
  const auto direct = sim::simulateScan(sc, 0, 2);
  const sim::World w(sc, 0.0);
  const cv::Mat img = cv::imread(seq.imagePath(0));
  const auto cam = *seq.camera();
  std::size_t seen = 0, blue = 0;
  for (std::size_t i = 0; i < direct.points.size(); ++i) {
    if (direct.solid[i] < 0 || w.solids()[direct.solid[i]].name != "parked_1") continue;
    const auto px = cam.project(direct.points[i].xyz().cast<double>());
    if (!px) continue;
    ++seen;
    const cv::Vec3b c = img.at<cv::Vec3b>(int(px->y()), int(px->x()));
    blue += c[0] > c[1] && c[0] > c[2];
  }
  ASSERT_GT(seen, 100u);
  EXPECT_GT(double(blue) / double(seen), 0.9);
}

TEST(SimCamera, CullingTheSolidsChangesNoPixel) {
  // renderImage tests, per band of 32 columns, only the solids the band's rays can reach: every
  // pixel as when each ray tests every solid. On the default street, a 20 % climb (the ego
  // pitched) and a street of thin poles, with the camera looking ahead, left, back (its bands
  // straddle azimuth pi), and up or down (bands whose rays turn round the vertical). A
  // quarter-size KITTI camera, at each scene's middle frame.
  std::vector<sim::Scenario> scenes = {sim::defaultScenario()};
  for (const char* name : {"ground_slope", "poles_drift"})
    scenes.push_back(sim::loadScenario(
        (fs::path(CLEANMAP_SOURCE_DIR) / "datasets/scenarios" / (std::string(name) + ".ini"))
            .string()));
  PinholeCamera small = sim::kittiCamera();
  small.P.topRows<2>() *= 0.25;
  small.width = 310;
  small.height = 94;
  const std::map<std::string, Eigen::Matrix3d> turns = {
      {"ahead", Eigen::Matrix3d::Identity()},
      {"left", Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix()},
      {"back", Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix()},
      {"up", Eigen::AngleAxisd(1.3, Eigen::Vector3d::UnitY()).toRotationMatrix()},
      {"down", Eigen::AngleAxisd(-1.55, Eigen::Vector3d::UnitY()).toRotationMatrix()}};
  for (const auto& sc : scenes)
    for (const auto& [name, R] : turns) {
      PinholeCamera cam = small;
      cam.T_cam_lidar = small.T_cam_lidar * Eigen::Isometry3d(R);
      const cv::Mat culled = sim::renderImage(sc, sc.frames / 2, cam, 2, true);
      const cv::Mat every = sim::renderImage(sc, sc.frames / 2, cam, 2, false);
      ASSERT_TRUE(culled.isContinuous() && every.isContinuous());
      ASSERT_EQ(culled.total(), every.total());
      EXPECT_EQ(0, std::memcmp(culled.data, every.data, culled.total() * culled.elemSize()))
          << sc.name << " looking " << name;
    }
  // The climb ahead at the camera's full width (its bands' own angle, a quarter of its rows):
  // the tops of the solids beside the road, seen from the pitched ego, in every frame.
  PinholeCamera wide = sim::kittiCamera();
  wide.P.row(1) *= 0.25;
  wide.height = 94;
  for (int k = 0; k < scenes[1].frames; ++k) {
    const cv::Mat culled = sim::renderImage(scenes[1], k, wide, 2, true);
    const cv::Mat every = sim::renderImage(scenes[1], k, wide, 2, false);
    EXPECT_EQ(0, std::memcmp(culled.data, every.data, culled.total() * culled.elemSize()))
        << "frame " << k;
  }
}

TEST(SimLidar, MotionDuringTheSweepDistortsOnlyAwayFromTheFront) {
  // Walls across the road 20 m ahead and behind; the ego drives at 10 m/s. The sweep passes the
  // front (azimuth 0) at the frame's time: the front wall is where it is without sweep motion.
  // Behind, the sweep starts 0.05 s early and ends 0.05 s late: the rear wall is up to 0.5 m off.
  auto sc = sim::parseScenario(R"(
[sensor]
range_noise = 0
dropout = 0
camera = false
[ego]
path = 0 0  100 0
speed = 10
[box]
center = 25 0
size = 2 40 6
[box]
center = -25 0
size = 2 40 6
)",
                               "walls");
  const auto still = sim::simulateScan(sc, 0, 2);
  sc.sensor.sweep_motion = true;
  const auto moving = sim::simulateScan(sc, 0, 2);
  // Match the same ray in both scans by its direction (no noise: a point lies on its ray).
  auto key = [](const PointXYZI& p) {
    const double r = p.xyz().norm();
    return std::make_pair(std::lround(std::atan2(p.y, p.x) * 1e4),
                          std::lround(std::asin(p.z / r) * 1e4));
  };
  std::map<std::pair<long, long>, std::size_t> index;
  for (std::size_t j = 0; j < moving.points.size(); ++j) index[key(moving.points[j])] = j;
  double front = 0, rear = 0;
  std::size_t nf = 0, nr = 0;
  for (std::size_t i = 0; i < still.points.size(); ++i) {
    if (still.surface[i] != sim::Surface::kStatic) continue;
    const auto& p = still.points[i];
    const auto it = index.find(key(p));
    if (it == index.end()) continue;
    const double d = (moving.points[it->second].xyz() - p.xyz()).norm(), az = std::atan2(p.y, p.x);
    if (std::abs(az) < 0.02) front = std::max(front, d), ++nf;
    if (std::abs(az) > M_PI - 0.05) rear = std::max(rear, d), ++nr;
  }
  ASSERT_GT(nf, 20u);
  ASSERT_GT(nr, 20u);
  EXPECT_LT(front, 0.02);  // the front slice's time is within 0.7 ms of the frame time
  EXPECT_GT(rear, 0.4);
  EXPECT_LT(rear, 0.55);
}
