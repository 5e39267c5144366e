// SPDX-License-Identifier: BSD-3-Clause
// The laser pipeline on cleanmap-sim scenes with exact truth (issue #4): the default scenario's
// IoU bar, one named test per hard case with its own bound, ground removal on the slope / curb /
// ramp scenes. Bounds sit a little below the values measured (doc/BENCHMARK.md, "Simulated").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <initializer_list>
#include <map>
#include <tuple>

#include "cleanmap/core/ground.h"
#include "cleanmap/core/metrics.h"
#include "cleanmap/core/sensor.h"
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

// The scenario seen by the lidar model `m` (its rings and azimuth step) instead of its own.
sim::Scenario seenBy(sim::Scenario sc, SensorModel m) {
  sc.sensor.model = m;
  sc.sensor.elevations = ringElevations(m);
  sc.sensor.azimuth_step_deg = sensorPreset(m).azimuth_step_deg;
  return sc;
}

// following_car's street with the ego at 2 m/s and its one car, "leader", `ahead` m in front of
// it in its lane, driving on at `speed`.
sim::Scenario carAhead(double ahead, double speed) {
  auto sc = scenario("following_car");
  sc.ego_speed = 2.0;
  EXPECT_EQ(sc.movers.size(), 1u);
  auto& car = sc.movers.at(0);
  car.name = "leader";
  car.path = {{ahead, -2.5}, {290.0, -2.5}};
  car.speed = speed;
  return sc;
}

struct CaseResult {
  MosCounts all;
  std::map<std::string, MosCounts> per_mover;  // over the points that hit each mover
  std::size_t relabelled_static = 0, relabelled_moving = 0;
  std::size_t image_units = 0;  // objects the camera check looked at
  MosCounts low;  // over the points less than 0.12 m over the road (z = 0 on the flat scenes)
  std::vector<MosCounts> per_frame;                               // by scan index
  std::map<std::string, std::vector<MosCounts>> per_mover_frame;  // per_mover by scan index
  std::vector<std::size_t> order;  // the scan indices in the order the sink got them
  MosCounts frames(std::size_t from, std::size_t to) const {  // scans from..to-1
    MosCounts c;
    for (std::size_t k = from; k < to; ++k) c += per_frame.at(k);
    return c;
  }
  // `mover`'s points in scans from..to-1, printed with their number.
  MosCounts moverScans(const std::string& mover, std::size_t from, std::size_t to) const {
    MosCounts c;
    for (std::size_t k = from; k < to; ++k) c += per_mover_frame.at(mover).at(k);
    std::printf("  %s in scans %zu-%zu: recall %.3f of %llu\n", mover.c_str(), from, to - 1,
                c.recall(), static_cast<unsigned long long>(c.tp + c.fn));
    return c;
  }
};

// Simulates every frame and runs the laser pipeline with the poses the scenario reports (the true
// ones unless it has a pose drift).
// With `odometry`, each frame also carries input odometry (GICP's guess): the scenario's wheel
// odometry where it has one (`[ego] odometry`), else the true pose.
// With `images`, each frame carries its rendered camera image (DESIGN §3).
CaseResult runCase(const sim::Scenario& sc, const PipelineParams& params = {},
                   std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>>* poses = nullptr,
                   std::vector<PoseInfo>* pose_info = nullptr, bool odometry = false,
                   bool images = false, const Eigen::Matrix3d* mount = nullptr) {
  std::vector<sim::SimScan> truth(sc.frames);
  CaseResult res;
  LaserPipeline pipe(params, [&](ScanResult&& r) {
    res.image_units += r.stats.image_units;
    for (const uint32_t i : r.relabelled_index) {  // the camera's relabellings, against truth
      const GtClass g = gtClass(truth[r.index].labels[i]);
      res.relabelled_static += g == GtClass::kStatic;
      res.relabelled_moving += g == GtClass::kMoving;
    }
    if (pose_info) pose_info->push_back(r.pose_info);
    const auto& t = truth[r.index];
    if (poses) poses->emplace_back(r.pose, t.pose);  // (estimated or given, true)
    const MosCounts c = compareLabels(r.labels, t.labels, "frame " + std::to_string(r.index));
    res.all += c;
    res.per_frame.resize(std::max(res.per_frame.size(), r.index + 1));
    res.per_frame[r.index] = c;
    res.order.push_back(r.index);
    for (std::size_t i = 0; i < t.labels.size(); ++i)
      if ((t.pose * t.points[i].xyz().cast<double>()).z() < 0.12)
        res.low += compareLabels({r.labels[i]}, {t.labels[i]}, "x");
    const sim::World w(sc, t.time);
    for (std::size_t i = 0; i < t.labels.size(); ++i) {
      if (t.solid[i] < 0 || w.solids()[t.solid[i]].surface != sim::Surface::kMover) continue;
      const std::string& name = w.solids()[t.solid[i]].name;
      const MosCounts c_i = compareLabels({r.labels[i]}, {t.labels[i]}, "x");
      res.per_mover[name] += c_i;
      auto& frames = res.per_mover_frame[name];
      frames.resize(std::max(frames.size(), r.index + 1));
      frames[r.index] += c_i;
    }
    truth[r.index] = {};  // memory bounded by the window, as the app
  });
  if (images) pipe.setCamera(sim::kittiCamera());
  for (int k = 0; k < sc.frames; ++k) {
    truth[k] = sim::simulateScan(sc, k, 2);
    Frame f = sim::frameOf(sim::SimScan(truth[k]), k);
    if (mount) {  // the same rays from a lidar tilted by `mount` on the vehicle
      for (auto& p : f.scan.points) {
        const Eigen::Vector3f q = mount->transpose().cast<float>() * p.xyz();
        p.x = q.x(), p.y = q.y(), p.z = q.z();
      }
      f.scan.pose.linear() = f.scan.pose.linear() * *mount;
      f.mount = Eigen::Isometry3d(*mount);
    }
    if (odometry) f.odometry = sc.ego_odometry >= 0 ? *sim::odometryPose(sc, k) : truth[k].pose;
    if (images) f.image = Image{sim::renderImage(sc, k, sim::kittiCamera(), 2), truth[k].time};
    pipe.push(std::move(f));
  }
  pipe.finish();
  for (const auto& [name, c] : res.per_mover)
    std::printf("  %s: %s recall %.3f precision %.3f (%llu moving points)\n", sc.name.c_str(),
                name.c_str(), c.recall(), c.precision(), (unsigned long long)(c.tp + c.fn));
  std::printf("  %s: all: precision %.3f recall %.3f IoU %.3f\n", sc.name.c_str(),
              res.all.precision(), res.all.recall(), res.all.iou());
  return res;
}

}  // namespace

TEST(SimCases, DefaultScenarioIoUAtLeast0_8) {
  const auto r = runCase(sim::defaultScenario());
  EXPECT_GE(r.all.iou(), 0.8);  // issue #4 bar; measured 0.985 (0.949 before kCarryMatch)
  EXPECT_GE(r.all.precision(), 0.95);
  // The overtaking car waits 0.5 s, then drives off at 10 m/s: the labels call it moving from
  // scan 1 (it moves over the next 0.5 s), the test finds it from scan 6. Rule 4 backwards
  // carries it back to its start (doc/OBJECTS.md); it moves 1 m a scan there, beyond rule 4's
  // 0.9 m, and until kCarryMatch (1.5 m) it was not carried at all (recall 0.06 in scans 1-5).
  MosCounts start;
  for (std::size_t k = 1; k < 6; ++k) start += r.per_frame.at(k);
  EXPECT_GE(start.recall(), 0.85);  // measured 0.92 (the other movers' misses included)
}

TEST(SimCases, AFarWalkerOfFewReturnsIsFoundPast28Metres) {
  // doc/OBJECTS.md rule 2, "Far and few": the default street with the ego at 0.6 x (the sweep's
  // ego_slow). In scans 16-22 the pedestrian crosses 28-30 m ahead, 17-18 returns a scan, fewer
  // than min_moving (20), and the windowed test flags 15-18 of them. Measured 0.9985, and 0.908
  // with object.far_points = 0 (those scans lost whole); precision 1.000 either way. (0.965 and
  // 0.875 before rule 6's feet looked for the road a ring away, doc/OBJECTS.md.)
  auto sc = sim::defaultScenario();
  sc.ego_speed *= 0.6;
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("pedestrian").recall(), 0.97);
  EXPECT_GE(r.all.precision(), 0.999);
  PipelineParams off;
  off.object.far_points = 0;
  const auto r_off = runCase(sc, off);
  EXPECT_LE(r_off.per_mover.at("pedestrian").recall(), 0.93);
  EXPECT_GE(r_off.all.precision(), 0.999);
}

TEST(SimCases, CarFollowingTheEgoAtTheSameSpeed) {
  // Measured 0.983 (0.961 before its roof's stripes went with it at a dense lidar, 1.3 and 4.3 m
  // behind its front face, rule 6; 0.870 before rule 4 at the start carried it back to scans 0-2,
  // doc/OBJECTS.md; 0.848 before its returns within 0.09 m of the road went with it, rule 6; 0.866
  // before beams grazing a flat surface stopped voting, DESIGN §2b: its first scans' roof points,
  // under its own roof in the next scans, were seen empty only by the beams grazing that roof).
  const auto r = runCase(scenario("following_car"));
  EXPECT_GE(r.per_mover.at("follower").recall(), 0.97);
  EXPECT_GE(r.all.precision(), 0.97);
  // doc/OBJECTS.md rule 6: the car's face down to the road is the car's. Its returns less than
  // 0.12 m over the road: recall 0.766 (0.433 before, when those under the ground stage's 0.09 m
  // step were ground refined in its cells, DESIGN §2a); nothing of the road itself taken.
  std::printf("  under 0.12 m: recall %.3f, %llu road points labelled moving\n", r.low.recall(),
              (unsigned long long)r.low.fp);
  EXPECT_GE(r.low.recall(), 0.7);
  EXPECT_EQ(r.low.fp, 0u);
}

TEST(SimCases, ACarPullingAwaySlowlyAheadStaysMoving) {
  // A car 9 m ahead of the ego (2 m/s) pulling away at 2.8 m/s: 0.08 m a scan, so the scans
  // before see its back's place inside its body and the near scans after see its back within the
  // beam model's margin; its roof's evidence was beams grazing that roof (DESIGN §2b). Rule 4
  // under 10 % finds the previous scan's object moved, and half of its points (all of them) gone
  // for the far half of the later scans (doc/OBJECTS.md): recall 0.904 (0.737 before, the whole
  // car lost from scan 22 of 30; 0.697 with the grazing beams alone). Scan 21 keeps only its
  // lowest part (hysteresis with no moving point above its foot).
  const auto r = runCase(carAhead(9.0, 2.8));
  EXPECT_GE(r.per_mover.at("leader").recall(), 0.85);  // measured 0.904
  EXPECT_GE(r.all.precision(), 0.97);                  // measured 1.000
}

TEST(SimCases, CarThatStopsAndStartsAgain) {
  // Moving along its own length at 6 m/s next to a slow ego: the DS test alone sees its sides
  // occupied in most scans of the window (the highway tanker's failure: 0.39 without the object
  // consensus, doc/OBJECTS.md). While it stands it must not be flagged.
  // It stops at 1.2 s (scan 12) and starts again at 2.7 s; the labels call it moving while it
  // moved over +-0.5 s (scans 12-16 and 23-27). Just after it stopped it is held while the scans
  // before it saw part of it empty (rule 4, arriving): scans 12-14. In 15-16 most of the 5 scans
  // before it saw it there; its outline matches half a window before shifted 0.45-1.05 m back,
  // where this scan sees the road behind its rear empty (rule 7's old evidence; the earlier scan
  // saw its new place inside its body). Once it has stood for more than half a window it is
  // static. Found moving again from scan 28, it is carried back to the half window before that
  // (rule 4 backwards, doc/OBJECTS.md): scans 23-27, none before.
  const auto r = runCase(scenario("stop_and_go"));
  // measured 0.995 (0.945 before the old evidence, 0.776 before rule 4 backwards, 0.708 before
  // "arriving", 0.62 without hysteresis)
  EXPECT_GE(r.per_mover.at("stop_go_car").recall(), 0.97);
  EXPECT_GE(r.all.precision(), 0.97);
  MosCounts stopped, standing, starting;
  for (std::size_t k = 12; k < 17; ++k) stopped += r.per_frame.at(k);
  for (std::size_t k = 17; k < 23; ++k) standing += r.per_frame.at(k);
  for (std::size_t k = 23; k < 28; ++k) starting += r.per_frame.at(k);
  EXPECT_GE(stopped.recall(), 0.9);   // measured 0.995 (0.58 before the old evidence, 0 before)
  EXPECT_EQ(standing.fp, 0u);         // it stands: nothing of it moving
  EXPECT_GE(starting.recall(), 0.9);  // measured 0.96 (0 before)
}

TEST(SimCases, ACarDrawingAwaySlowlyStaysMovingWhileItLeavesItsPlace) {
  // The same car at 3 m/s, the ego following at 2: as it draws away after its stop only its rear
  // shows, under 10 % of it tests moving, and rule 4 held it only down to 10 % (recall 0.377).
  // The object the previous scan moved whole stays moving where the scans after it see it leave
  // (doc/OBJECTS.md): scans 30-34 (drawing away), and 12-13, just after it stopped (moving by
  // the labels' +-0.5 s; 36 of its ~40 moving points there are empty for the later scans, seen
  // from the ego closing in); the scans it stands in after those stay static. Through the last
  // K / 2 scans (35-39) too few scans follow to see it leave and it stays as it was: 7-11 % of
  // it held there before, 96 % now (recall 0.617 before). Since beams grazing a flat top no
  // longer vote (DESIGN §2b) scans 12-13 are static (the car stands; its roof's alarms held it),
  // and the far half of the later scans sees it leave in 30-34 (0.376 without that test).
  auto sc = scenario("stop_and_go");
  for (auto& m : sc.movers) m.speed *= 0.5;
  const auto r = runCase(sc);
  // measured 0.789 (0.742 before "arriving" held it in scans 12-13 again, 0.718 and 0.765 before)
  EXPECT_GE(r.per_mover.at("stop_go_car").recall(), 0.75);
  EXPECT_GE(r.all.precision(), 0.97);  // measured 1.000
}

TEST(SimCases, AnOncomingCarStaysMovingWhileOnlyItsFrontShowsIt) {
  // car_stops_5s at half speed: the oncoming car drives on at 3 m/s after its stop and passes the
  // ego 5 m to the side. 11-10 m ahead (scans 65-69) only its front tests moving, 4-8 % of it,
  // and rule 4 held it only where the scans after it saw it leave; an oncoming car shows them
  // its front inside itself, its side still occupied: lost in those scans (recall 0.025 there).
  // It has just arrived: the scans before it saw its front's place empty (doc/OBJECTS.md).
  auto sc = scenario("car_stops_5s");
  for (auto& m : sc.movers) m.speed *= 0.5;
  const auto r = runCase(sc);
  MosCounts passing;
  for (std::size_t k = 65; k < 70; ++k) passing += r.per_frame.at(k);
  std::printf("  scans 65-69: recall %.3f precision %.3f\n", passing.recall(), passing.precision());
  EXPECT_GE(passing.recall(), 0.9);
  EXPECT_GE(r.all.precision(), 0.99);
}

TEST(SimCases, ACarThatStopsIsCarriedBackThroughTheScansItStoodIn) {
  // doc/OBJECTS.md rule 4 backwards, "Came to a stop": car_stops_5s' oncoming car drives at
  // 6 m/s from the run's first scan and stops 18 m ahead in scan 5; the labels call it moving
  // to scan 9. Head-on, only future scans see it in scans 0-4 (its old front inside its later
  // body), and rule 7 measures scans 8-9 alone (earlier, the shift exceeds its 1.5 m). Carried
  // back from there, it stood in scans 5-7 by the track then known, and the chain stopped:
  // scans 3-7 had none of their 3,527 returns moving. Its track, seeded standing by the pair
  // (8, 9), gives it no velocity to move at in the run's first scans, held deeper than the usual
  // depth: there it goes on where it steps more than a voxel a scan to its next known place (63
  // of scans 0-2's 1,564 returns moving before; "Held deeper at a run's start").
  const auto r = runCase(scenario("car_stops_5s"));
  const MosCounts first = r.frames(0, 3), stopping = r.frames(3, 8);
  std::printf("  scans 0-2: recall %.3f, scans 3-7: recall %.3f\n", first.recall(),
              stopping.recall());
  EXPECT_GE(first.recall(), 0.8);      // measured 0.948 (0.040 before)
  EXPECT_GE(stopping.recall(), 0.8);   // measured 0.946 (0 before)
  EXPECT_GE(r.all.precision(), 0.99);  // measured 1.000
  // The parked car 12 m ahead: the ring that meets its roof (0.23 m under the sensor) met it
  // 0.1-0.3 m further in the next scans, within 2 sigma of P's range, and voted empty at the
  // roof's returns of scans 0-3, whose windows are one-sided (137 static returns flagged until
  // the hundred-and-fourteenth session). Beams meeting a flat surface within their grazing
  // stretch now vote nothing there (DESIGN §2b, grazing beams): none flagged.
  EXPECT_LT(r.all.fp, 14u);  // measured 0
}

// doc/OBJECTS.md rule 2, "Level with the surface around it": the walker stands on a sidewalk
// 0.12 m up (not ground); parted from the wall and from the sidewalk beyond him, his component
// holds the sidewalk's returns just in front of his face, within foot_reach of it, and took them
// (20-50 a scan in scans 22-29, 254 false positives in all). The sidewalk around him, in the
// other components, shows that they are level with it.
TEST(SimCases, PedestrianWalkingAlongAWall) {
  const auto r = runCase(scenario("pedestrian_wall"));
  std::printf("  false positives %zu, walker recall %.4f\n", static_cast<std::size_t>(r.all.fp),
              r.per_mover.at("walker").recall());
  EXPECT_GE(r.per_mover.at("walker").recall(), 0.97);  // measured 0.980 (0.851 without wall_gap)
  EXPECT_GE(r.all.precision(), 0.95);                  // the wall behind must stay static
  EXPECT_LT(r.all.fp, 130u);  // the sidewalk in front of his face: measured 66 (254 before)
}

// doc/OBJECTS.md rule 1, "Beside a wall": the walker, his back 5 cm from the wall, shared its
// voxels and its structure, and the object rules never took him whole: at half speed the scans
// of his first second found none of him (scans 0-7), a few of his returns after. Parted from the
// wall, he is an object that rules 2 and 4 take whole and rule 4 backwards carries into his
// first scans, and his sides' returns by the wall, in its voxels, are his. Measured at half
// speed: recall 0.976 (0.921 with his sides the wall's, 0.622 with wall_gap 0), precision 0.991
// (0.995): rule 2's foot takes the sidewalk within 0.15 m of his feet.
TEST(SimCases, AWalkerAgainstAWallIsAnObjectOfHisOwn) {
  auto sc = scenario("pedestrian_wall");
  for (auto& m : sc.movers) m.speed *= 0.5;
  PipelineParams off;
  off.object.wall_gap = 0;
  const auto r = runCase(sc), r_off = runCase(sc, off);
  EXPECT_GE(r.per_mover.at("walker").recall(), 0.95);  // his sides by the wall his
  std::printf("  scans 0-7: recall %.3f (wall_gap 0: %.3f)\n", r.frames(0, 8).recall(),
              r_off.frames(0, 8).recall());
  EXPECT_GE(r.frames(0, 8).recall(), 0.7);  // measured 0.934 (0.000 with wall_gap 0)
  EXPECT_LE(r_off.frames(0, 8).recall(), 0.3);
  EXPECT_GE(r.all.precision(), 0.97);
}

TEST(SimCases, SlowWalkersAreFoundByTheirEmptyRuns) {
  // DESIGN §2b, "Empty runs": the walkers of pedestrian_wall and poles_drift at half speed
  // (0.75 m/s). pedestrian_wall's walks towards the sensor: the scans before see his place
  // empty, the scans after see his front nearer than P, and the votes said static in scans 2-17.
  // Measured 0.62 and 0.98 (0.33 and 0.72 with ds.empty_run = 0); pedestrian_wall's 0.976 since
  // rule 1 parts him from the wall (AWalkerAgainstAWallIsAnObjectOfHisOwn).
  for (const auto& [name, bound] :
       {std::pair<std::string, double>{"pedestrian_wall", 0.55}, {"poles_drift", 0.9}}) {
    auto sc = scenario(name);
    for (auto& m : sc.movers) m.speed *= 0.5;
    const auto r = runCase(sc);
    std::printf("  %s at half speed: walker recall %.3f, precision %.3f\n", name.c_str(),
                r.per_mover.at("walker").recall(), r.all.precision());
    EXPECT_GE(r.per_mover.at("walker").recall(), bound) << name;
    EXPECT_GE(r.all.precision(), 0.98) << name;  // the wall, the poles stay static
  }
}

TEST(SimCases, PedestrianWalkingAlongAWallSeenFromALowMount) {
  // From 0.8 m the HDL-64E sees the wall only up to 1.0 m and the walker shadows that band: the
  // wall breaks at him and he joins a "vehicle-sized" piece of it, under 10 % moving. Rule 2 of
  // the object consensus turned it static (recall 0.352); his group is a body (doc/OBJECTS.md).
  auto sc = scenario("pedestrian_wall");
  sc.sensor.height = 0.8;
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("walker").recall(), 0.70);  // measured 0.926 (0.786 before wall_gap)
  EXPECT_GE(r.all.precision(), 0.95);                  // measured 0.985: the wall stays static
}

// DESIGN §2b: the window spans 1 s, not 10 scans. A 20 Hz lidar compares the walker with the scans
// of the same second as a 10 Hz one (K 20, every other one): with K fixed at 10 (half a second)
// he overlaps where he stood in most of his window (recall 0.359, measured).
TEST(SimCases, PedestrianWalkingAlongAWallSeenAt20Hz) {
  auto sc = scenario("pedestrian_wall");
  sc.rate_hz = 20;
  sc.frames *= 2;  // the same 3 s
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("walker").recall(), 0.75);  // measured 0.982 (0.982 at 10 Hz)
  EXPECT_GE(r.all.precision(), 0.95);
}

// doc/OBJECTS.md rule 2's foot: from 0.8 m the sidewalk beside the parked car (0.12 m up, not
// ground) joins the car's returns as it pulls out, and the car's component turned it moving with
// the car (precision 0.833, scans 26-29).
TEST(SimCases, ACarLeavingTheCurbSeenFromALowMount) {
  auto sc = scenario("parked_leaves");
  sc.sensor.height = 0.8;
  const auto r = runCase(sc);
  // measured 0.996 (0.833 with object.foot_height = 0; 0.971 while rule 4 backwards turned the
  // sidewalk of scan 25 with the car, doc/OBJECTS.md)
  EXPECT_GE(r.all.precision(), 0.97);
  EXPECT_GE(r.per_mover.at("leaving_car").recall(), 0.60);  // measured 0.791 (0.664 before)
}

TEST(SimCases, MoverEnteringTheCropFromFarAway) {
  const auto r = runCase(scenario("entering_far"));
  EXPECT_GE(r.per_mover.at("far_car").recall(), 0.90);  // measured 0.96
  EXPECT_GE(r.all.precision(), 0.97);
}

TEST(SimCases, ACarComingUpBehindIsMovingFromTheFirstScan) {
  // following_car, the ego's motion slowed to 6 m/s: the car behind comes up at 2 m/s and shows
  // the sensor its front only. That front's place was empty in the scans before each one, inside
  // the car in those after it, so in the first scans, with few scans before them, the windowed
  // test found none of it (scans 0-2, recall 0.000) until the scans before showed it arriving.
  // The object the next scans moved whole is now carried back to them (doc/OBJECTS.md rule 4
  // backwards).
  auto sc = scenario("following_car");
  sc.ego_speed = 6.0;
  const auto r = runCase(sc);
  ASSERT_EQ(r.order.size(), static_cast<std::size_t>(sc.frames));
  for (std::size_t k = 0; k < r.order.size(); ++k) EXPECT_EQ(r.order[k], k);  // in scan order
  MosCounts first;
  for (std::size_t k = 0; k < 5; ++k) first += r.per_frame.at(k);
  std::printf("  first 5 scans: recall %.3f precision %.3f\n", first.recall(), first.precision());
  EXPECT_GE(first.recall(), 0.9);
  EXPECT_GE(first.precision(), 0.99);
  EXPECT_GE(r.all.precision(), 0.99);
}

TEST(SimCases, ACarFallingBehindIsMovingFromTheRunsFirstScan) {
  // following_car with its follower at 4 m/s behind the ego at 8: in the world it moves towards
  // the ego's old places, so only the scans before a scan see its face's place empty, and the
  // run's first scan has none. Rule 4 backwards carried it back from scan 6 to the held scans
  // 1-5; scan 0 was handed on already (0 of its 2,232 returns). A run's first H + 2 scans are
  // held until 2 (H + 2) are decided (doc/OBJECTS.md rule 4 backwards, "Held deeper at a run's
  // start").
  auto sc = scenario("following_car");
  sc.movers.at(0).speed = 4.0;
  const auto r = runCase(sc);
  std::printf("  scan 0: recall %.3f\n", r.per_frame.at(0).recall());
  EXPECT_GE(r.per_frame.at(0).recall(), 0.85);  // measured 0.915 (0.000 before)
  EXPECT_GE(r.all.recall(), 0.95);              // measured 0.963 (0.893)
  EXPECT_GE(r.all.precision(), 0.99);           // measured 1.000
  PipelineParams usual;                         // `object.hold_start = 0`: the usual depth alone
  usual.object.hold_start = false;
  EXPECT_LT(runCase(sc, usual).per_frame.at(0).recall(), 0.1);  // measured 0.000
}

TEST(SimCases, ARunShorterThanHalfAWindowIsHandedOnWhole) {
  // Every scan of a 3-scan run is still held when the run ends (rule 4 backwards holds the last
  // ceil(K / 2) + 2 decided); finish() hands each on once, in order, labelled.
  auto sc = scenario("following_car");
  sc.frames = 3;
  const auto r = runCase(sc);
  ASSERT_EQ(r.order.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(r.order[k], k);
  EXPECT_GT(r.all.tp + r.all.fp + r.all.tn + r.all.fn, 0u);
}

TEST(SimCases, CyclistOccludedForPartOfTheWindow) {
  const auto r = runCase(scenario("occluded"));
  EXPECT_GE(r.per_mover.at("hidden_cyclist").recall(), 0.90);  // measured 0.97
  EXPECT_GE(r.all.precision(), 0.97);
}

TEST(SimCases, ACyclistTheEgoOvertakesStaysMovingWhenItsSideFallsApart) {
  // The default street at half speed: the cyclist rides at 2 m/s along his length (1.8 m) and
  // the ego closes in from behind at 6. The windowed test sees little of him moving (his side is
  // occupied in most of the window); rule 4 holds him scan after scan. Seen 11.5 m ahead, 1.2 m
  // to the side, the HDL-64E's columns lie 0.35 m apart along his side, more than the grouping's
  // voxel: in scan 31 his side's far end was a component of its own, the rest was smaller than
  // the object the previous scan moved whole, and he was lost from there to the end (recall
  // 0.45). The pieces beside it in azimuth, within the test's cone, now count to its size
  // (doc/OBJECTS.md rule 4).
  auto sc = scenario("default");
  for (auto& m : sc.movers) m.speed *= 0.5;
  sc.sensor.camera = false;
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("cyclist").recall(), 0.9);  // measured 0.947 (0.45 before)
  EXPECT_GE(r.all.precision(), 0.99);                  // measured 0.999
}

TEST(SimCases, ACarPullingOutOfItsPlaceIsAnObjectOfItsOwn) {
  // parked_leaves: the car parked at the curb 14 m ahead pulls out after 2.5 s. The sidewalk
  // (0.12 m up, above the ground stage's step) joined it to the street's walls and poles into one
  // structure, where rule 2 does not apply: only its tested back and front moved, 1,276 of its
  // 3,729 returns in scan 26 (recall 0.615). Low surfaces no longer link it (doc/OBJECTS.md
  // rule 1). The labels call it moving from scan 21 (it moves 0.5 m over +-0.5 s); it stands
  // until 2.5 s and was found from scan 26 (recall 0.738). It is carried back to the half window
  // before (rule 4 backwards), also in scan 22, where the kerb joined its component.
  const auto r = runCase(scenario("parked_leaves"));
  EXPECT_GE(r.per_mover.at("leaving_car").recall(), 0.95);  // measured 0.978
  EXPECT_GE(r.all.precision(), 0.99);                       // measured 0.998
  MosCounts standing;
  for (std::size_t k = 21; k < 26; ++k) standing += r.per_frame.at(k);
  EXPECT_GE(standing.recall(), 0.9);  // measured 0.96 (0 before), precision 0.995
  EXPECT_GE(standing.precision(), 0.99);
}

TEST(SimCases, ACarPullingAwayAcceleratesFromRest) {
  // The same car pulling away at 2 m/s2 (a city car's), not at 5 m/s at once (`accel`): the labels
  // call it moving from scan 28, 0.21 s after it starts (0.5 m over +-0.5 s), not from scan 21.
  // It is found once it is faster and carried back (doc/OBJECTS.md rule 4 "Backwards") at the
  // velocity of the two scans that found it, lower than its later one. The standing car (about
  // 4,000 returns a scan, static or ignored in scans 20-27) stays static.
  auto sc = scenario("parked_leaves");
  sc.movers.at(0).accel = 2;
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("leaving_car").recall(), 0.95);  // measured 0.988
  EXPECT_GE(r.all.precision(), 0.99);                       // measured 0.997
  MosCounts starting, standing;
  for (std::size_t k = 28; k < 33; ++k) starting += r.per_frame.at(k);
  EXPECT_GE(starting.recall(), 0.9);      // measured 0.984
  EXPECT_GE(starting.precision(), 0.99);  // measured 0.995
  for (std::size_t k = 20; k < 28; ++k) standing += r.per_frame.at(k);
  EXPECT_LE(standing.fp, 500u);  // measured 46
}

TEST(SimCases, ACarFollowingInTheNextLaneKeepsItsSide) {
  // doc/OBJECTS.md rule 1, "Coarse columns": the default street with its movers pulling away at
  // 2 m/s2 (`accel`): the overtaking car trails the ego 20-27 m back in the next lane, 4.3 m to
  // the side, never overtaking. Its side, met at about 10 degrees, shows the HDL-64E's columns
  // (0.18 degrees) 0.4-0.5 m apart along it: slices apart from the car, and a side moving along
  // itself keeps its own space occupied, so only the car's face was found (recall 0.82). The
  // links of its columns join the slices to the car, and rule 2 turns them with it.
  auto sc = scenario("default");
  for (auto& m : sc.movers) m.accel = 2;
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("overtaking_car").recall(), 0.93);  // measured 0.96 (0.82 before)
  EXPECT_GE(r.all.precision(), 0.99);                          // measured 1.000 (0.960 before)
  // Standing 14-16 m behind in scans 0-4, static by the labels: its centroid creeps towards its
  // front as the ego drives away, and the chain from the scans it drove in took that for a
  // motion (4,379 false positives where a run's first scans were held deeper for every object;
  // doc/OBJECTS.md rule 4 backwards, "Held deeper at a run's start").
  std::printf("  scans 0-4: %llu false positives\n", (unsigned long long)r.frames(0, 5).fp);
  EXPECT_LE(r.frames(0, 5).fp, 100u);  // measured 9
  PipelineParams off;
  off.object.column_links = false;
  EXPECT_LT(runCase(sc, off).per_mover.at("overtaking_car").recall(), 0.9);
}

// Rule 7 (doc/OBJECTS.md, "Measured"): a vehicle sliding along its own side keeps that side
// occupied, and the windowed test flags only its ends, over a few scans. Its outline, matched
// against the scans half a window before and after, shows the shift where its rear or front is
// in view, and that scan sees the place the rear left empty.
TEST(SimCases, ACarCreepingAwayBesideTheSensorIsMeasuredMoving) {
  // stop_and_go with the car braking and pulling away at 2 m/s2: it stands 5 m to the left and
  // 3.5 m ahead of the ego (which follows at 2 m/s), then creeps off at 0.6-2.6 m/s. The
  // windowed test flags 0-4 % of its ~10,000 returns a scan there; the labels call it moving
  // from scan 30.
  auto sc = scenario("stop_and_go");
  sc.movers.at(0).accel = 2;
  const auto r = runCase(sc);
  MosCounts creeping;
  for (std::size_t k = 30; k < 37; ++k) creeping += r.per_frame.at(k);
  EXPECT_GE(creeping.recall(), 0.8);   // measured 0.984 (0 without rule 7)
  EXPECT_GE(r.all.precision(), 0.99);  // measured 1.000
  EXPECT_GE(r.all.recall(), 0.9);      // measured 0.958 (0.254 without)
  // Without rule 7, and without the empty runs (DESIGN §2b), which find most of it too (0.979
  // in scans 30-36).
  PipelineParams off;
  off.object.measure = false;
  off.ds.empty_run = 0;
  const auto r_off = runCase(sc, off);
  MosCounts creeping_off;
  for (std::size_t k = 30; k < 37; ++k) creeping_off += r_off.per_frame.at(k);
  EXPECT_LT(creeping_off.recall(), 0.2);
}

TEST(SimCases, AQueueCreepingPastAStandingSensorIsMeasuredMoving) {
  // queue_stop_go: three cars crawl at 2 m/s 2.5 m beside a standing ego, stop for 2 s and go
  // on. Their sides slide along themselves; the windowed test alone flagged 4.7 % of their
  // returns (doc/BENCHMARK.md). Their outlines show the shift where their ends are in view.
  const auto r = runCase(scenario("queue_stop_go"));
  // measured 0.996 (0.987 before the run's first scans were carried back, 0.946 before the old
  // evidence, 0.804 by faces only, 0.088 without)
  EXPECT_GE(r.all.recall(), 0.95);
  EXPECT_GE(r.all.precision(), 0.99);  // measured 1.000
  // The run's first two scans: rule 7 measures no scan without the H before it, so only rule 4
  // backwards reaches them, from the first objects rule 7 measured (doc/OBJECTS.md rule 4
  // backwards, "A run's first scans").
  MosCounts first = r.per_frame.at(0);
  first += r.per_frame.at(1);
  std::printf("  scans 0-1: recall %.3f\n", first.recall());
  EXPECT_GE(first.recall(), 0.8);  // measured 0.925 (0.475 before)
}

// Rule 4's arrival, "How far it came" (doc/OBJECTS.md): queue_stop_go with its cars braking at
// 2 m/s2 (`accel`). The first car stands 3.5 m beside the standing ego from 2.0 s; it came 0.16 m
// in its last half second, and the labels call scans 21-22 static. The scans before saw a few
// returns at its leading end empty (the ego's beams passed just beyond it there), and rule 4 held
// the car as arriving (20,815 and 20,838 false positives, precision 0.965). Each of them saw the
// place 0.2 m further in occupied: its side. What is left in scan 21 is the windowed test's own
// flags at that end (scan 20, which came 0.25 m, is held and put none of the car into the
// duplicate filter).
// Where the vehicle came further, the place further in was empty, or hidden, in one of those
// scans: stop_and_go as shipped stops at once from 6 m/s at 1.2 s, and scans 13-14 are held by
// their arrival alone (recall 0.05 without it); truck_crawl seen by an OS1-64 at 512 columns
// arrives at its leading end in its last scans, its side seen at 14 degrees, and its old end hid
// the place further in (asking one scan to see it empty lost scans 74-79 whole).
TEST(SimCases, ACarBrakingToAStandHasNotArrived) {
  auto sc = scenario("queue_stop_go");
  for (auto& m : sc.movers) m.accel = 2;
  const auto braking = runCase(sc);
  std::printf("  braking, scans 21-22: %llu false positives; all: precision %.4f, recall %.4f\n",
              (unsigned long long)braking.frames(21, 23).fp, braking.all.precision(),
              braking.all.recall());
  EXPECT_LE(braking.frames(21, 23).fp, 1000u);  // measured 234 (41,653 before)
  EXPECT_GE(braking.all.precision(), 0.99);     // measured 0.9998 (0.965)
  EXPECT_GE(braking.all.recall(), 0.99);        // measured 0.9969 (0.9969)
  const auto at_once = runCase(scenario("stop_and_go"));
  std::printf("  stop_and_go, scans 13-14: recall %.4f\n", at_once.frames(13, 15).recall());
  EXPECT_GE(at_once.frames(13, 15).recall(), 0.9);
  auto truck = seenBy(scenario("truck_crawl"), SensorModel::kOs1_64);
  truck.sensor.azimuth_step_deg = 360.0 / 512;
  const auto crawling = runCase(truck);
  std::printf("  truck_crawl at 512 columns, scans 74-79: recall %.4f\n",
              crawling.frames(74, 80).recall());
  EXPECT_GE(crawling.frames(74, 80).recall(), 0.9);
}

// doc/OBJECTS.md rule 4, "Half a window ago": stop_and_go with the ego at 0.6 x. The car stops at
// once from 6 m/s in scan 12. In scan 14 only its leading 0.6 m (empty for scans 9-11, occupied
// in 12-13) was moving for the K / 2 scans before it, 15 returns under min_moving (20), and the
// scan kept none of its 1,459. Its leading 1.2 m read empty from the window's far end in the scans
// before it (an empty run, 7 of K): it came less than half a window ago. Once it has stood for
// half a window it is static.
TEST(SimCases, ACarThatStoppedAtOnceIsHeldForHalfAWindow) {
  auto sc = scenario("stop_and_go");
  sc.ego_speed *= 0.6;
  const auto r = runCase(sc);
  std::printf("  scan 14: recall %.4f; scans 12-16: %.4f\n", r.frames(14, 15).recall(),
              r.frames(12, 17).recall());
  EXPECT_GE(r.frames(14, 15).recall(), 0.9);   // measured 0.992 (0 before)
  EXPECT_GE(r.frames(12, 17).recall(), 0.95);  // measured 0.994 (0.794 before)
  EXPECT_EQ(r.frames(17, 23).fp, 0u);          // it stands: nothing of it moving
  EXPECT_GE(r.all.precision(), 0.99);          // measured 1.000
}

TEST(SimCases, AWaitingCarWhoseSideComesAndGoesIsCarriedBack) {
  // doc/OBJECTS.md rule 4 backwards, "Its side comes and goes": the default street's overtaking
  // car waits 17-20 m behind the ego for half a second and drives off, moving by the labels from
  // its first scans. Seen from behind at an angle, its side grazes, joins its object in one scan
  // and is a slice of its own in the next: the objects moved whole step by half the side, and no
  // centroid matched them. With the ego at 1.5x and with the movers at 0.5x, the car was carried
  // back to none of scans 1-5.
  const auto firstScans = [](const CaseResult& r) {
    MosCounts c;
    for (std::size_t k = 1; k <= 5; ++k) c += r.per_frame.at(k);
    return c;
  };
  auto fast = scenario("default");
  fast.ego_speed *= 1.5;
  const auto f = runCase(fast);
  std::printf("  ego 1.5x, scans 1-5: recall %.3f\n", firstScans(f).recall());
  EXPECT_GE(f.per_mover.at("overtaking_car").recall(), 0.95);  // measured 0.975 (0.857 before)
  EXPECT_GE(firstScans(f).recall(), 0.8);                      // measured 0.896 (0.077 before)
  EXPECT_GE(f.all.precision(), 0.99);                          // measured 1.000
  // Standing in scan 0 (static by the labels), before it drives off: not carried back there
  // (doc/OBJECTS.md rule 4 backwards, "Held deeper at a run's start"; 1,092 false positives
  // where every object went on).
  std::printf("  scan 0: %llu false positives\n", (unsigned long long)f.per_frame.at(0).fp);
  EXPECT_LE(f.per_frame.at(0).fp, 100u);  // measured 0
  auto slow = scenario("default");
  for (auto& m : slow.movers) m.speed *= 0.5;
  const auto s = runCase(slow);
  std::printf("  movers 0.5x, scans 1-5: recall %.3f\n", firstScans(s).recall());
  EXPECT_GE(s.per_mover.at("overtaking_car").recall(), 0.9);  // measured 0.943 (0.804 before)
  EXPECT_GE(firstScans(s).recall(), 0.8);                     // measured 0.922 (0.084 before)
  EXPECT_GE(s.all.precision(), 0.99);                         // measured 0.999
}

TEST(SimCases, ATruckCrawlingPastAStandingSensorIsMeasuredByItsSide) {
  // truck_crawl: a 12 m truck crawls at 1.2 m/s 2 m beside a standing ego. Its front and rear
  // face away from the sensor: only its side is in view, sliding along itself, occupied in
  // every scan (recall 0 without rule 7's side route). Its trailing end's place is seen empty.
  const auto r = runCase(scenario("truck_crawl"));
  EXPECT_GE(r.all.recall(), 0.9);      // measured 0.999 (0.000 before rule 7)
  EXPECT_GE(r.all.precision(), 0.99);  // measured 1.000
}

TEST(SimCases, ATruckCrawlingAtHalfThatSpeedIsMeasuredByItsEnds) {
  // doc/OBJECTS.md rule 7, "A side's ends": the same truck at 0.6 m/s, 0.3 m a half window, two
  // cells. Matched whole, its side matched in place against one half-window scan and 0.9-1.35 m
  // along itself against the other (what each saw of its grazing rear): recall 0. Its front end,
  // 0-5 m ahead of the sensor, tells: it came 0.3 m into a place the earlier scan saw empty, and
  // the later scan holds it 0.3 m on, where this scan sees empty.
  auto sc = scenario("truck_crawl");
  for (auto& m : sc.movers) m.speed *= 0.5;
  const auto r = runCase(sc);
  std::printf("  truck at 0.6 m/s: precision %.4f, recall %.4f\n", r.all.precision(),
              r.all.recall());
  EXPECT_GE(r.all.recall(), 0.9);      // measured 0.9992 (0.000 before)
  EXPECT_GE(r.all.precision(), 0.99);  // measured 1.000
}

TEST(SimCases, AWalkerAlongAWallDoesNotMoveTheWall) {
  // pedestrian_wall with the ego at 0.6 x: the walker, his back 5 cm from a 30 m wall, is one
  // component with it in some scans. The walker matches shifted and its old place is empty,
  // but in the middle of the wall's side, not at its end: the wall stays (rule 7's side route
  // first took it whole, precision 0.031).
  auto sc = scenario("pedestrian_wall");
  sc.ego_speed *= 0.6;
  const auto r = runCase(sc);
  EXPECT_GE(r.all.precision(), 0.99);  // measured 0.995 (0.997 before wall_gap)
  EXPECT_GE(r.all.recall(), 0.7);      // measured 0.970 (0.779 before wall_gap)
}

namespace {

struct GroundScore {
  double ground_recall = 0, object_kept = 0;
};

GroundScore groundScore(const std::string& name) {
  const auto sc = scenario(name);
  std::size_t g = 0, g_found = 0, o = 0, o_kept = 0;
  for (int k = 0; k < sc.frames; ++k) {
    const auto s = sim::simulateScan(sc, k, 2);
    const auto flags = segmentGround(s.points, GroundParams{}, 30.0, -sc.sensor.height);
    for (std::size_t i = 0; i < s.points.size(); ++i) {
      const auto& p = s.points[i];
      if (std::abs(p.x) > 30 || std::abs(p.y) > 30) continue;
      if (s.surface[i] == sim::Surface::kGround) ++g, g_found += flags[i];
      if (s.surface[i] == sim::Surface::kStatic || s.surface[i] == sim::Surface::kMover)
        ++o, o_kept += !flags[i];
    }
  }
  const GroundScore r{double(g_found) / double(g), double(o_kept) / double(o)};
  std::printf("  %s: ground recall %.3f, object points kept %.3f\n", name.c_str(), r.ground_recall,
              r.object_kept);
  return r;
}

}  // namespace

TEST(SimGround, RoadClimbingAt20Percent) {
  const auto r = groundScore("ground_slope");
  EXPECT_GE(r.ground_recall, 0.95);  // measured 1.000
  EXPECT_GE(r.object_kept, 0.97);    // measured 0.988
}

TEST(SimGround, CurbsSidewalksAndADrivewayRamp) {
  // 12 cm curbs stop the propagation by design (step > s = 9 cm): parts of the raised
  // sidewalks stay unfound. Curb and ramp faces count as neither ground nor object.
  const auto r = groundScore("ground_curb_ramp");
  EXPECT_GE(r.ground_recall, 0.80);  // measured 0.841
  EXPECT_GE(r.object_kept, 0.94);    // measured 0.961
}

TEST(SimCases, MoversOnCurvedPaths) {
  const auto r = runCase(scenario("curved_path"));
  EXPECT_GE(r.per_mover.at("turning_car").recall(), 0.88);  // measured 0.946
  EXPECT_GE(r.per_mover.at("arc_cyclist").recall(), 0.85);  // measured 0.913
  EXPECT_GE(r.all.precision(), 0.97);
}

TEST(SimCases, ThinPolesWithPoseDriftStayStatic) {
  // doc/SCAN_CONFLICT.md: 6-8 cm sign poles every 7 m, the ego at 8 m/s with poses drifting 1 %
  // of the distance travelled. Beams of other scans pass beside a pole and return from it at
  // the same time; the paper's rule alone calls parts of the poles moving, ours does not.
  const auto sc = scenario("poles_drift");
  const auto r = runCase(sc);
  EXPECT_GE(r.all.precision(), 0.97);                  // measured 0.991
  EXPECT_GE(r.per_mover.at("walker").recall(), 0.90);  // measured 0.955
  PipelineParams paper;
  paper.ds.scan_conflict = 1.0;
  EXPECT_LT(runCase(sc, paper).all.precision(), 0.90);  // measured 0.822: the case is real
}

// GICP odometry (DESIGN §2.1) on the default street with the sensor moving during each sweep
// (6 m/s: the points of one sweep are up to 0.3 m off either way, not de-skewed). The first given
// pose anchors the trajectory. Bounds: per-frame relative error within 2 cm and 0.1 deg (range
// noise is 1 cm and the scan is aligned at 1 m spacing; the sweep distortion is symmetric about
// the front and largely cancels), drift within 1 % of the distance, and the moving-point scores
// within 0.03 of the run with true poses. Measured: see doc/BENCHMARK.md.
TEST(SimCases, GicpTracksASweepingSensor) {
  auto sc = sim::defaultScenario();
  sc.frames = 30;
  sc.sensor.sweep_motion = true;
  PipelineParams p;
  p.poses = PoseSource::kGicp;
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> poses;
  const auto est = runCase(sc, p, &poses);
  ASSERT_EQ(poses.size(), 30u);
  std::vector<double> dt, dr;
  double dist = 0;
  for (std::size_t k = 1; k < poses.size(); ++k) {
    const Eigen::Isometry3d rel_est = poses[k - 1].first.inverse() * poses[k].first;
    const Eigen::Isometry3d rel_true = poses[k - 1].second.inverse() * poses[k].second;
    const Eigen::Isometry3d e = rel_true.inverse() * rel_est;
    dt.push_back(e.translation().norm());
    dr.push_back(Eigen::AngleAxisd(e.linear()).angle() * 180 / M_PI);
    dist += rel_true.translation().norm();
  }
  std::sort(dt.begin(), dt.end());
  std::sort(dr.begin(), dr.end());
  const double end = (poses.back().second.inverse() * poses.back().first).translation().norm();
  std::printf(
      "  gicp sweep: RPE median %.4f m / %.4f deg, max %.4f m; end error %.3f m over %.1f m\n",
      dt[dt.size() / 2], dr[dr.size() / 2], dt.back(), end, dist);
  EXPECT_LE(dt[dt.size() / 2], 0.02);
  EXPECT_LE(dr[dr.size() / 2], 0.1);
  EXPECT_LE(end, 0.01 * dist);
  PipelineParams given;
  const auto ref = runCase(sc, given);
  EXPECT_NEAR(est.all.recall(), ref.all.recall(), 0.03);
  EXPECT_NEAR(est.all.precision(), ref.all.precision(), 0.03);
}

// doc/OBJECTS.md rule 2's raised parts: at 20 m/s scan 20 of this street passes a pedestrian
// and a cyclist on a sidewalk that is not ground there; it joined them to a pole and a wall's foot
// in one object-sized component, which turned moving (5,840 false positives, precision 0.929).
TEST(SimCases, AStreetAt20MetresASecond) {
  auto sc = sim::defaultScenario();
  sc.ego_speed = 20;
  const auto r = runCase(sc);
  EXPECT_GE(r.all.precision(), 0.99);
  EXPECT_GE(r.all.recall(), 0.9);
}

// DESIGN §2.0: at 14 m/s a sweep's first and last points are 0.7 m from where the scan's pose puts
// them, and static surfaces look moving to the scans after (the parked truck of `occluded`:
// precision 0.842 with sensor.deskew 0, 1.000 de-skewed). The simulator's frames carry each point's
// time, so auto de-skews them with the motion between the given poses.
TEST(SimCases, AHighwaySweepIsDeskewed) {
  auto sc = scenario("occluded");
  sc.ego_speed = 14;
  sc.sensor.sweep_motion = true;
  const auto r = runCase(sc);
  EXPECT_GE(r.all.precision(), 0.98);
  EXPECT_GE(r.all.recall(), 0.9);
  PipelineParams off;
  off.sensor.deskew = DeskewMode::kOff;
  EXPECT_LT(runCase(sc, off).all.precision(), 0.9);  // the scene shows the distortion
}

// DESIGN §2.0: which scans are de-skewed (auto: those with point times; 1: all, the times from
// the azimuth; 0: none), and by how much: at 14 m/s the sweep's ends move half a sweep, 0.7 m,
// the first scan too (by the motion to the second); a run of one scan has no motion to undo.
TEST(SimCases, DeskewFollowsTheModeAndThePointTimes) {
  auto sc = sim::defaultScenario();
  sc.frames = 4;
  sc.ego_speed = 14;
  sc.sensor.sweep_motion = true;
  std::vector<Frame> frames;
  for (int k = 0; k < sc.frames; ++k)
    frames.push_back(sim::frameOf(sim::simulateScan(sc, k, 2), k));
  auto run = [&](DeskewMode mode, bool times, int n) {
    PipelineParams p;
    p.sensor.deskew = mode;
    std::vector<ScanStats> stats;
    LaserPipeline pipe(p, [&](ScanResult&& r) { stats.push_back(r.stats); });
    for (int k = 0; k < n; ++k) {
      Frame f = frames[static_cast<std::size_t>(k)];
      if (!times) f.scan.point_time.clear();
      pipe.push(std::move(f));
    }
    pipe.finish();
    return stats;
  };
  for (const auto& [mode, times, deskewed] :
       {std::tuple{DeskewMode::kAuto, true, true}, std::tuple{DeskewMode::kAuto, false, false},
        std::tuple{DeskewMode::kOn, false, true}, std::tuple{DeskewMode::kOff, true, false}}) {
    const auto stats = run(mode, times, sc.frames);
    ASSERT_EQ(stats.size(), 4u);
    for (const auto& st : stats) {
      EXPECT_EQ(st.deskewed, deskewed ? 1u : 0u) << int(mode) << " " << times;
      if (deskewed) {
        EXPECT_NEAR(st.deskew_max_shift, 0.7, 0.05) << int(mode) << " " << times;
      }
    }
  }
  const auto one = run(DeskewMode::kAuto, true, 1);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].deskewed, 0u);
}

namespace {

// A recording that starts at `speed` (sweep motion, 30 frames) registered by GICP alone: the
// per-step translation errors (in scan order), the path's length and the end error, against the
// simulator's poses.
struct StartAtSpeed {
  CaseResult est;
  std::vector<PoseInfo> info;
  std::vector<double> step_error;
  double dist = 0, end = 0;
  double first_step = 0;  // the first step's error in the world frame (any mount)
};

StartAtSpeed startAtSpeed(sim::Scenario sc, double speed, const Eigen::Matrix3d* mount = nullptr) {
  sc.frames = 30;
  sc.ego_speed = speed;
  sc.sensor.sweep_motion = true;
  PipelineParams p;
  p.poses = PoseSource::kGicp;
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> poses;
  StartAtSpeed r;
  r.est = runCase(sc, p, &poses, &r.info, false, false, mount);
  for (std::size_t k = 1; k < poses.size(); ++k) {
    const Eigen::Isometry3d rel_est = poses[k - 1].first.inverse() * poses[k].first;
    const Eigen::Isometry3d rel_true = poses[k - 1].second.inverse() * poses[k].second;
    r.step_error.push_back((rel_true.inverse() * rel_est).translation().norm());
    r.dist += rel_true.translation().norm();
  }
  if (!poses.empty())
    r.end = (poses.back().second.inverse() * poses.back().first).translation().norm();
  if (poses.size() > 1)
    r.first_step = ((poses[1].first.translation() - poses[0].first.translation()) -
                    (poses[1].second.translation() - poses[0].second.translation()))
                       .norm();
  return r;
}

}  // namespace

// DESIGN §2.1 "Starting at speed": a recording that starts at 14 m/s with no odometry. The first
// guess is a standstill, 1.4 m off; along this street's facades GICP then finds only the corridor
// and refuses (degenerate), and without the search along the forward axis every later scan kept
// that standstill (precision 0.15, each step 1.4 m short). With it the second scan locks on, and
// the sweeps (sweep_motion) are de-skewed by the motion GICP finds (DESIGN §2.0).
TEST(SimCases, GicpLocksOnWhenTheRecordingStartsAtSpeed) {
  const StartAtSpeed r = startAtSpeed(sim::defaultScenario(), 14);
  ASSERT_EQ(r.info.size(), 30u);
  EXPECT_GT(r.info[1].start_guesses, 0);
  // Each guess is screened with 8 GICP iterations, and only the best runs on (issue #16).
  EXPECT_LE(r.info[1].guess_iterations, 8 * r.info[1].start_guesses + 30);
  std::vector<double> dt = r.step_error;
  std::sort(dt.begin(), dt.end());
  std::printf(
      "  start at 14 m/s: RPE median %.4f m, max %.4f m; end error %.3f m over %.1f m; %d guesses, "
      "%d iterations\n",
      dt[dt.size() / 2], dt.back(), r.end, r.dist, r.info[1].start_guesses,
      r.info[1].guess_iterations);
  EXPECT_LE(dt[dt.size() / 2], 0.02);
  EXPECT_LE(dt.back(), 0.1);
  EXPECT_LE(r.end, 0.01 * r.dist);
  EXPECT_GE(r.est.all.precision(), 0.97);
}

// DESIGN §2.1 "Starting at speed" with a lidar mounted facing left (yawed 90 degrees on the car,
// a rawlog's sensorPose), at 10 m/s along flat facades: the search and the facing surfaces are
// the car's forward axis, the lidar's -y, not its x (then the facades were the "facing" surfaces,
// the standstill fitted them, and the run kept it: end error 28.96 m over 29 m).
TEST(SimCases, GicpLocksOnAtSpeedWithALidarMountedSideways) {
  const Eigen::Matrix3d mount = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).matrix();
  const StartAtSpeed r = startAtSpeed(scenario("occluded"), 10, &mount);
  ASSERT_EQ(r.info.size(), 30u);
  EXPECT_GT(r.info[1].start_guesses, 0);
  std::printf("  sideways at 10 m/s: first step error %.3f m, end error %.3f m over %.1f m\n",
              r.first_step, r.end, r.dist);
  EXPECT_LE(r.first_step, 0.05);
  EXPECT_LE(r.end, 0.01 * r.dist);
  EXPECT_GE(r.est.all.precision(), 0.97);
}

// DESIGN §2.1 "Starting at speed", the accepted standstill: at 10 m/s the first guess is 1 m off,
// at the correspondences' reach, and GICP accepts a standstill along this street of flat facades
// (their points, sampled alike by the same beams, fit it best: fitness 0.9988 against 0.9732 at the
// truth), then keeps it (precision 0.079, end error 29 m over 39 m). The parked truck's faces
// across the street say where the sensor is: the guesses along the forward axis run and the one
// that fits them best wins.
TEST(SimCases, GicpLocksOnAt10MetresASecondAlongFlatFacades) {
  const StartAtSpeed r = startAtSpeed(scenario("occluded"), 10);
  ASSERT_EQ(r.info.size(), 30u);
  EXPECT_GT(r.info[1].start_guesses, 0);
  EXPECT_LE(r.step_error.front(), 0.05);  // the first step, which the standstill held
  std::printf("  start at 10 m/s: end error %.3f m over %.1f m, precision %.3f\n", r.end, r.dist,
              r.est.all.precision());
  EXPECT_LE(r.end, 0.01 * r.dist);
  EXPECT_GE(r.est.all.precision(), 0.95);
}

// Input odometry (rawlog actions, DESIGN §2.1) is GICP's initial guess after the first scan:
// every later scan reports the odometry guess, is accepted, and stays within 5 cm of the truth.
TEST(SimCases, GicpStartsFromInputOdometry) {
  auto sc = sim::defaultScenario();
  sc.frames = 20;
  PipelineParams p;
  p.poses = PoseSource::kGicp;
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> poses;
  std::vector<PoseInfo> info;
  runCase(sc, p, &poses, &info, true);
  ASSERT_EQ(info.size(), 20u);
  EXPECT_EQ(info[0].guess, "given");  // the first given pose anchors the trajectory
  for (std::size_t k = 1; k < info.size(); ++k) {
    EXPECT_EQ(info[k].guess, "odometry") << "scan " << k;
    EXPECT_TRUE(info[k].accepted) << "scan " << k << ": " << info[k].status;
    const Eigen::Isometry3d e = poses[k].second.inverse() * poses[k].first;
    EXPECT_LE(e.translation().norm(), 0.05) << "scan " << k;
  }
}

// DESIGN §2.1 step 4: following_car is a corridor where the follower, driving with the ego, is
// the only hold along the road: GICP alone estimates no motion at all (doc/BENCHMARK.md,
// thirty-fourth session). With wheel odometry drifting 1 % per metre as the guess, the alignment
// the follower holds is refused as straying from the odometry, the corridor's as degenerate, and
// the trajectory is the odometry's: 0.5 % of the path over 10 scans, labels as with given poses.
TEST(SimCases, GicpWithWheelOdometryBehindAFollowingCar) {
  auto sc = scenario("following_car");
  sc.ego_odometry = 0.01;
  PipelineParams p;
  p.poses = PoseSource::kGicp;
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> poses;
  std::vector<PoseInfo> info;
  const auto r = runCase(sc, p, &poses, &info, true);
  ASSERT_EQ(poses.size(), static_cast<std::size_t>(sc.frames));
  const double err = test::relativeError(poses, 10);
  std::printf("  following_car, gicp + odometry: 10-scan error %.2f %% of the path; scan 1: %s\n",
              100 * err, info[1].status.c_str());
  EXPECT_LE(err, 0.03);
  EXPECT_NE(info[1].status.find("disagrees with the odometry"), std::string::npos)
      << info[1].status;
  EXPECT_GE(r.per_mover.at("follower").recall(), 0.80);  // the given-pose bars (above)
  EXPECT_GE(r.all.precision(), 0.97);
}

// DESIGN §3: the camera check on the default street with poses drifting 6 % of the distance
// travelled (the laser test then flags parts of parked cars and facades). It must not cost the
// laser's recall (the flat black overtaking car survives through the depth test), and what it
// relabels static must be mostly static. Measured: doc/BENCHMARK.md, "Camera validation".
TEST(SimCases, CameraCheckKeepsMoversAndRelabelsOnlyStaticPoints) {
  auto sc = sim::defaultScenario();
  sc.frames = 25;
  sc.ego_pose_drift = 0.06;
  PipelineParams laser;
  laser.image.enabled = false;
  // The vote on the drift's false positives: the poses as given (aligned, few are left; the next
  // tests but one).
  PipelineParams vote;
  vote.image.align = false;
  const auto off = runCase(sc, laser, nullptr, nullptr, false, true);
  const auto on = runCase(sc, vote, nullptr, nullptr, false, true);
  std::printf(
      "  laser only: P %.4f R %.4f; with images: P %.4f R %.4f; relabelled %zu static, "
      "%zu moving\n",
      off.all.precision(), off.all.recall(), on.all.precision(), on.all.recall(),
      on.relabelled_static, on.relabelled_moving);
  EXPECT_EQ(off.relabelled_static + off.relabelled_moving, 0u);  // laser only: nothing relabelled
  EXPECT_EQ(off.image_units, 0u);
  EXPECT_GT(on.image_units, 20u);  // the camera did look at the moving objects
  EXPECT_GE(on.all.recall(), off.all.recall() - 0.03);
  EXPECT_GE(on.per_mover.at("overtaking_car").recall(),
            off.per_mover.at("overtaking_car").recall() - 0.03);
  // The drift makes the laser flag parts of walls and parked cars; those in the camera's view
  // look the same in most cells, so the object vote relabels them (measured: +0.0046, 187 truly
  // static points, none moving; with "one changed cell keeps it moving": nothing relabelled).
  // Before beams grazing a flat surface stopped voting (DESIGN §2b) the laser also flagged the
  // parked cars' roofs and bonnets, and the camera took +0.0165 (700 points).
  EXPECT_GE(on.all.precision(), off.all.precision() + 0.003);
  EXPECT_GT(on.relabelled_static, 100u);
  const std::size_t relabelled = on.relabelled_static + on.relabelled_moving;
  EXPECT_GT(double(on.relabelled_static) / double(std::max<std::size_t>(relabelled, 1)), 0.6);
}

namespace {

// `sc` with its rendered images, laser only and then with the camera stage (default parameters).
std::pair<CaseResult, CaseResult> laserThenImages(const sim::Scenario& sc) {
  PipelineParams laser;
  laser.image.enabled = false;
  auto off = runCase(sc, laser, nullptr, nullptr, false, true);
  auto on = runCase(sc, PipelineParams{}, nullptr, nullptr, false, true);
  std::printf("  laser only: P %.4f R %.4f; with images: P %.4f R %.4f\n", off.all.precision(),
              off.all.recall(), on.all.precision(), on.all.recall());
  return {std::move(off), std::move(on)};
}

}  // namespace

// DESIGN §3 "Camera poses", the #14 bar: a street whose written poses drift (10 % of the path,
// a random walk of 6 cm per scan and axis) makes the laser flag textured walls and parked cars.
// Each camera aligned on the previous scan's road gives the window its true relative poses:
// precision rises by at least 0.25, recall and the movers' recall stay.
TEST(SimCases, CameraAlignedPosesRemoveTheDriftFalsePositives) {
  auto sc = sim::defaultScenario();
  sc.frames = 30;
  sc.ego_pose_drift = 0.10;
  const auto [off, on] = laserThenImages(sc);
  // Measured (cleanmap on the same street): 0.740 / 0.860 -> 0.996 / 0.860.
  EXPECT_GE(on.all.precision(), off.all.precision() + 0.25);
  EXPECT_GE(on.all.recall(), off.all.recall() - 0.03);
  for (const auto& [name, c] : off.per_mover)
    EXPECT_GE(on.per_mover.at(name).recall(), c.recall() - 0.03) << name;
}

// DESIGN §3, "Objects rule 4 holds": a car 20 m ahead drawing away at 0.6 m/s while the ego
// closes in at 2 m/s, as kitti_highway's car 16 m ahead. Rule 4 holds it under 10 % (the far half
// of the later scans sees it gone). Over the window its image moves a few pixels and its depth by
// less than the depth test resolves, so voted on by the camera it looked the same: 534 of its
// points relabelled, and rule 4 forgets what the camera relabelled (recall 0.169). Left to the
// laser, as the camera's vote was cast when the object was moved whole: 0.904, as laser only.
// DESIGN §3: the camera leaves the objects rule 4 holds and those the empty runs found (§2b); a
// car drawing away along its axis at 0.6 m/s changes its images too little over the window.
TEST(SimCases, ACarDrawingAwayAlongTheCameraAxisKeepsWhatRule4Holds) {
  const auto [off, on] = laserThenImages(carAhead(20.0, 0.6));
  EXPECT_GE(off.per_mover.at("leader").recall(), 0.85);  // measured 0.937 (0.904 without runs)
  EXPECT_GE(on.per_mover.at("leader").recall(), off.per_mover.at("leader").recall() - 0.03);
  // measured 0 (534 when the camera voted on rule 4's hold, 2,848 on the runs' objects)
  EXPECT_LE(on.relabelled_moving, 50u);
}

// The same bar on another seed of the drift, whose random walk steps 0.155 and 0.251 m between
// two scans (6 cm per scan and axis has such steps now and then). Until the thirty-sixth session
// a correction over 0.15 m was refused as "beyond any drift": those two steps stayed in every
// window that spans them, and the laser flagged the walls around them (precision 0.258 -> 0.312
// with images). A correction beyond image.align_small_shift is kept where the images' error falls
// by 70 % (these: 88 % and 93 %).
TEST(SimCases, CameraAlignedPosesCorrectTheDriftsLargerSteps) {
  auto sc = sim::defaultScenario();
  sc.frames = 30;
  sc.ego_pose_drift = 0.10;
  sc.seed = 9;
  const auto [off, on] = laserThenImages(sc);
  // Measured (cleanmap on the same street): 0.258 / 0.864 -> 0.997 / 0.857.
  EXPECT_GE(on.all.precision(), off.all.precision() + 0.25);
  EXPECT_GE(on.all.precision(), 0.95);
  EXPECT_GE(on.all.recall(), off.all.recall() - 0.03);
}

// What the 70 % guards against: on curved_path (the ego at 3 m/s; a car and a cyclist turning
// across the road ahead) with the same drift, the road's alignment finds wrong minima 0.2-0.8 m
// away that lower the error by 30-58 % (not traced: aliasing, or the movers' pull). Kept, they
// made the laser flag the scene (precision 1.000 -> 0.32); the images must cost nothing here.
TEST(SimCases, CameraLinksRefuseWrongMinimaOnCurvedPaths) {
  auto sc = scenario("curved_path");
  sc.frames = 30;
  sc.ego_pose_drift = 0.10;
  sc.seed = 3;
  const auto [off, on] = laserThenImages(sc);
  // Measured (cleanmap): 1.000 / 0.930 -> 1.000 / 0.935.
  EXPECT_GE(on.all.precision(), off.all.precision() - 0.01);
  EXPECT_GE(on.all.recall(), off.all.recall() - 0.03);
}

// DESIGN §3 "Camera poses" and §2f: a link depends on its two scans alone, so a chunk that starts
// later (epochs of 10 scans, K = 5, as Regression.ChunksReproduceTheWholeRun) labels the scans it
// owns as the whole run does, with the cameras' corrections in play.
TEST(SimCases, ChunksWithCameraPosesReproduceTheWholeRun) {
  auto sc = sim::defaultScenario();
  sc.frames = 30;
  sc.ego_pose_drift = 0.10;
  PipelineParams p;
  p.ds.window_k = 5;
  p.epoch = 10;
  std::vector<Frame> frames;
  for (int k = 0; k < sc.frames; ++k) {
    sim::SimScan t = sim::simulateScan(sc, k, 2);
    const double time = t.time;
    frames.push_back(sim::frameOf(std::move(t), k));
    frames.back().image = Image{sim::renderImage(sc, k, sim::kittiCamera(), 2), time};
  }
  std::size_t aligned = 0;
  auto run = [&](int first) {
    std::map<long, Labels> out;
    LaserPipeline pl(p, [&](ScanResult&& r) {
      out[static_cast<long>(r.index)] = r.labels;
      aligned += r.stats.image_links_aligned;
    });
    pl.setCamera(sim::kittiCamera());
    for (int k = first; k < sc.frames; ++k) pl.push(Frame(frames[static_cast<std::size_t>(k)]));
    pl.finish();
    return out;
  };
  const auto whole = run(0);
  EXPECT_GT(aligned, 20u);  // the drift's steps were corrected
  const auto chunk = run(7);
  for (long s = 20; s < sc.frames; ++s) EXPECT_TRUE(chunk.at(s) == whole.at(s)) << "scan " << s;
}

// The depth test's threshold (DESIGN §3): a pedestrian walking along the camera's ray 0.5 m
// before a flat wall keeps his look from scan to scan; only his depth changes (about 1 m in the
// window, 6 % of 17 m). At 0.01 the depth test called him similar and 707 of his points were
// relabelled static (recall 0.836 -> 0.767); now none is.
TEST(SimCases, APedestrianWalkingAlongTheRayBeforeAWallStaysMoving) {
  auto sc = scenario("pedestrian_wall");
  sc.sensor.camera = true;
  PipelineParams laser;
  laser.image.enabled = false;
  const auto off = runCase(sc, laser, nullptr, nullptr, false, true);
  const auto on = runCase(sc, PipelineParams{}, nullptr, nullptr, false, true);
  EXPECT_GT(on.image_units, 10u);  // the camera looked at him
  EXPECT_GE(on.per_mover.at("walker").recall(), off.per_mover.at("walker").recall() - 0.03);
  EXPECT_LT(on.relabelled_moving, 50u);
}

// Issue #15: any lidar, any mount, default parameters (sensor.height = auto). The default street
// seen by each preset at 0.8, 1.73 and 2.5 m above the road (40 frames, no camera); the bar: IoU
// within 0.08 of the HDL-64E at 1.73 m (KITTI's mounting) on the same street.
namespace {

sim::Scenario sensorScene(SensorModel m, double height) {
  auto sc = seenBy(sim::defaultScenario(), m);
  sc.sensor.height = height;
  sc.sensor.camera = false;
  sc.name = std::string(sensorPreset(m).name) + "_at_" + std::to_string(height);
  return sc;
}

// One test per preset: the reference run once, then the preset at each height.
void expectNearHdl64At173(SensorModel m, std::initializer_list<double> heights) {
  const double ref = runCase(sensorScene(SensorModel::kHdl64, 1.73)).all.iou();
  for (const double height : heights) {
    const double iou = runCase(sensorScene(m, height)).all.iou();
    EXPECT_GE(iou, ref - 0.08) << sensorPreset(m).name << " at " << height << " m: IoU " << iou
                               << ", HDL-64E at 1.73 m: " << ref;
  }
}

}  // namespace

TEST(SimSensors, Vlp16At0_8And1_73And2_5m) {
  expectNearHdl64At173(SensorModel::kVlp16, {0.8, 1.73, 2.5});
}
TEST(SimSensors, Hdl32At0_8And1_73And2_5m) {
  expectNearHdl64At173(SensorModel::kHdl32, {0.8, 1.73, 2.5});
}
TEST(SimSensors, Hdl64At0_8And2_5m) {
  expectNearHdl64At173(SensorModel::kHdl64, {0.8, 2.5});
}
TEST(SimSensors, Os1_64At0_8And1_73And2_5m) {
  expectNearHdl64At173(SensorModel::kOs1_64, {0.8, 1.73, 2.5});
}
TEST(SimSensors, Os1_128At0_8And1_73And2_5m) {
  expectNearHdl64At173(SensorModel::kOs1_128, {0.8, 1.73, 2.5});
}

// DESIGN §2b "Coarse columns" and §2d: an Ouster at 1024 columns, sensor.model = auto. Its rings
// lie as close as the HDL-64E's, and it was taken for one (density 1, min_moving 20 for its
// 0.41 or 0.60): the OS1-64 found the walker along the wall in none of scans 0-16 (IoU 0.682).
// Measured right, its lower min_moving let the thin poles' alarms pass (precision 0.80): a 3-4
// cm pole 20 m away is narrower than a column, and the scans whose columns straddle it vote
// empty. A point its own scan shows narrower than a column gets no vote (kColumnIsolated).
// Measured: walker recall 0.890 / 0.903 (OS1-64 / OS1-128), precision 0.995 / 0.967; poles
// precision 1.000 / 1.000, walker 0.962 / 0.970.
// doc/OBJECTS.md rule 1, "A stretch of a wall": an Ouster's rings break the wall at the walker's
// shadow into a stretch under max_length, which took him whole in scans 0-6 (none of his returns
// found there, recall 0.890 / 0.901); asked as a structure is, it parts him. Measured: walker
// recall 0.970 / 0.980, scans 0-7 with the OS1-64 0.874 (0.126 before).
TEST(SimSensors, AnOusterFindsTheWalkerAlongTheWallAndKeepsTheThinPoles) {
  for (const SensorModel m : {SensorModel::kOs1_64, SensorModel::kOs1_128}) {
    const std::string lidar = sensorPreset(m).name;
    const auto wall = runCase(seenBy(scenario("pedestrian_wall"), m));
    std::printf("  %s pedestrian_wall: walker recall %.3f (scans 0-7 %.3f), precision %.3f\n",
                lidar.c_str(), wall.per_mover.at("walker").recall(), wall.frames(0, 8).recall(),
                wall.all.precision());
    EXPECT_GE(wall.per_mover.at("walker").recall(), 0.94) << lidar;
    EXPECT_GE(wall.frames(0, 8).recall(), 0.75) << lidar;
    EXPECT_GE(wall.all.precision(), 0.95) << lidar;
    const auto poles = runCase(seenBy(scenario("poles_drift"), m));
    std::printf("  %s poles_drift: walker recall %.3f, precision %.3f\n", lidar.c_str(),
                poles.per_mover.at("walker").recall(), poles.all.precision());
    EXPECT_GE(poles.all.precision(), 0.97) << lidar;
    EXPECT_GE(poles.per_mover.at("walker").recall(), 0.90) << lidar;
  }
}

// doc/OBJECTS.md rule 1, "A sparse lidar's rings", and rule 4 backwards: the walker along the
// wall seen by an HDL-32E is a slice a ring; only his lowest parted from the wall, his upper
// rings stayed the wall's, and rule 4 backwards found no part of his height: none of his returns
// in scans 0-6 (recall 0.868, scans 0-6 0.000). His slices join across rings, the group stands
// as high as from its floor, and a held part one ring step shorter than the object is it:
// measured recall 0.944, scans 0-6 0.838. A VLP-16's walker then went with the wall's ring over
// his head (rule 6's roof; 117 false positives): a walker has no roof (MoverRoofParams::narrow):
// measured recall 0.868 (0.824), 28 false positives (38). His lowest ring, level with the wall's,
// goes with the raised one a ring step over it (doc/OBJECTS.md rule 1, "His lowest ring"):
// measured VLP-16 0.920 (28 false positives), HDL-32E 0.957 (scans 0-6 0.965).
TEST(SimSensors, ASparseLidarFindsTheWalkerAlongTheWall) {
  const auto hdl32 = runCase(seenBy(scenario("pedestrian_wall"), SensorModel::kHdl32));
  std::printf("  HDL-32E: walker recall %.3f (scans 0-6 %.3f), precision %.3f\n",
              hdl32.per_mover.at("walker").recall(), hdl32.frames(0, 7).recall(),
              hdl32.all.precision());
  EXPECT_GE(hdl32.per_mover.at("walker").recall(), 0.94);
  EXPECT_GE(hdl32.frames(0, 7).recall(), 0.9);
  EXPECT_GE(hdl32.all.precision(), 0.96);
  const auto vlp16 = runCase(seenBy(scenario("pedestrian_wall"), SensorModel::kVlp16));
  std::printf("  VLP-16: walker recall %.3f, precision %.3f\n",
              vlp16.per_mover.at("walker").recall(), vlp16.all.precision());
  EXPECT_GE(vlp16.per_mover.at("walker").recall(), 0.9);
  EXPECT_GE(vlp16.all.precision(), 0.98);
}

// DESIGN §2b "Coarse columns" on sparse lidars too: poles_drift seen with columns coarser than the
// HDL-64E's at other rings. An HDL-32E's rings with 0.32-degree columns (its 20 Hz step), a
// VLP-16's with 0.4 and an OS1-64's with 0.70 (512 columns). Measured: precision 1.000 / 1.000 /
// 0.991 (0.581 / 0.331 / 0.503 with kColumnIsolated off), walker recall 0.959 / 0.905 / 0.912.
TEST(SimSensors, ThinPolesStayStaticWhateverTheColumnStep) {
  for (const auto& [m, step] : {std::pair<SensorModel, double>{SensorModel::kHdl32, 0.32},
                                {SensorModel::kVlp16, 0.4},
                                {SensorModel::kOs1_64, 360.0 / 512}}) {
    auto sc = seenBy(scenario("poles_drift"), m);
    sc.sensor.azimuth_step_deg = step;
    const auto r = runCase(sc);
    const std::string lidar = std::string(sensorPreset(m).name) + " at " + std::to_string(step);
    std::printf("  %s: precision %.3f, walker recall %.3f\n", lidar.c_str(), r.all.precision(),
                r.per_mover.at("walker").recall());
    EXPECT_GE(r.all.precision(), 0.97) << lidar;
    EXPECT_GE(r.per_mover.at("walker").recall(), 0.85) << lidar;
  }
}

// Rule 6 at a sparse lidar (doc/OBJECTS.md, MoverRoofParams): following_car seen by a VLP-16.
// The car 10 m behind the ego shows its front face; the ring over the face's top lands on its
// roof's rear edge 4.3 m further on, a stripe the grouping keeps apart, static, left behind in
// every scan (1,249 returns, all of the car's misses).
TEST(SimSensors, AFollowingCarsRoofStripeGoesWithItAtSixteenRings) {
  const auto sc = seenBy(scenario("following_car"), SensorModel::kVlp16);
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("follower").recall(), 0.97);  // measured 0.996
  EXPECT_GE(r.all.precision(), 0.99);                    // measured 1.000
  PipelineParams off;
  off.object.roofs = false;
  EXPECT_LT(runCase(sc, off).per_mover.at("follower").recall(), 0.93);  // measured 0.887
}

// Rule 4 backwards at a sparse lidar (doc/OBJECTS.md): `default` seen by a VLP-16.
// - Its cyclist, 22-23 m ahead, from behind ("Its side comes and goes"): scan 4 moved his back
//   (a face 0.03 m deep), scan 3 held his back and 0.5 m of his side, scans 0-2 his back alone:
//   each longer or shorter than the object the next scan moved, and none was carried back (0 of
//   39 returns in scans 0-3).
// - Its overtaking car, 15 m behind, about to pull out ("Its rings apart"): in scan 4 its roof's
//   stripe (45 returns, 0.05 m high) and its body (85, 0.67 m) were neither the size of the
//   object scan 5 moved whole (1.23 m high), and none of its 604 returns in scans 1-4 was
//   carried back.
TEST(SimSensors, ACyclistsBackAndACarsRingsAreCarriedBackAtSixteenRings) {
  const auto r = runCase(seenBy(scenario("default"), SensorModel::kVlp16));
  EXPECT_GE(r.moverScans("cyclist", 0, 4).recall(), 0.6);         // measured 0.795
  EXPECT_GE(r.moverScans("overtaking_car", 1, 5).recall(), 0.6);  // measured 0.934
  EXPECT_GE(r.all.precision(), 0.99);                             // measured 1.000
}

// Rule 4 backwards, "A slow seed" (doc/OBJECTS.md): `default` at half speed seen by a VLP-16.
// Its cyclist rides at 2 m/s 19-23 m ahead, 9-19 returns a scan: the windowed test flags 0-4 of
// them in scans 0-10, rule 4 backwards must carry him back. Each scan sees his back alone or his
// back and a piece of his side, so no two neighbours are the same size, and his ends move 0.2 m
// a scan, under the voxel a seed of two sizes needs: no track until scans 18-19, when scans 0-10
// had been handed on (0 of 130 returns). Over two scans his ends move 0.4 m.
TEST(SimSensors, ASlowCyclistsTrackIsSeededOverALongerSpanAtSixteenRings) {
  auto sc = seenBy(scenario("default"), SensorModel::kVlp16);
  for (auto& m : sc.movers) m.speed *= 0.5;
  const auto r = runCase(sc);
  EXPECT_GE(r.moverScans("cyclist", 0, 11).recall(), 0.6);  // measured 0.762 (0 before)
  EXPECT_GE(r.all.precision(), 0.99);  // measured 0.999 (6 returns of a parked car he rides out of)
}

// Rule 4 and rule 6 at a sparse lidar (doc/OBJECTS.md): stop_and_go seen by a VLP-16. Its car's
// rings come apart 10-17 m ahead. The ring over its top lands on its roof and runs along its side,
// a stripe the test flags in part (13-25 of 60-70 returns), all of it its own foot for rule 2:
// the rest stayed (recall 0.85 in scans 3-11). In the scan it stopped in, that stripe joined its
// body, and the centroid rose 0.2 m against the scan before: shifted by that, it was not the
// object the scan before moved whole (87 of 253 points), and scans 12-14 were lost.
TEST(SimSensors, ACarThatStopsKeepsItsSlicesAtSixteenRings) {
  const auto sc = seenBy(scenario("stop_and_go"), SensorModel::kVlp16);
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("stop_go_car").recall(), 0.95);  // measured 0.978 (0.845 before)
  EXPECT_GE(r.all.precision(), 0.99);                       // measured 1.000
  MosCounts driving, stopped;
  for (std::size_t k = 3; k < 12; ++k) driving += r.per_frame.at(k);
  for (std::size_t k = 12; k < 15; ++k) stopped += r.per_frame.at(k);
  EXPECT_GE(driving.recall(), 0.93);  // measured 0.97 (0.85 before)
  EXPECT_GE(stopped.recall(), 0.9);   // measured 0.98 (0 before)
}

// Coarse columns (doc/OBJECTS.md rules 1, 2 and 4): stop_and_go seen by an OS1-64 at 512
// columns (0.70 degrees). The car's side, seen at 20-25 degrees of incidence, is column slices
// that only its columns' links join. Turned moving by its rear face, the car's parts above its
// foot must join as its component did, or the slices without a moving return of their own stay
// static (26-90 of its 300-480 returns in each of scans 4-11, and 167-171 of its 206 in the
// last two). In the scan it stops in, its side shows a column less than in the scan before, and
// the centroids' difference is not its motion: it is the object the scan before moved whole by
// its ends (267 returns lost before).
TEST(SimSensors, ACarThatStopsKeepsItsSideAtFiveHundredTwelveColumns) {
  auto sc = seenBy(scenario("stop_and_go"), SensorModel::kOs1_64);
  sc.sensor.azimuth_step_deg = 360.0 / 512;
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("stop_go_car").recall(), 0.93);  // measured 0.996 (0.962 before)
  EXPECT_GE(r.all.precision(), 0.99);                       // measured 1.000
  MosCounts driving, stops, standing;
  for (std::size_t k = 0; k < 12; ++k) driving += r.per_frame.at(k);
  stops = r.per_frame.at(12);
  for (std::size_t k = 17; k < 23; ++k) standing += r.per_frame.at(k);
  EXPECT_GE(driving.recall(), 0.98);  // measured 0.994 (0.916 before)
  EXPECT_GE(stops.recall(), 0.9);     // measured 0.99 (0 before)
  EXPECT_EQ(standing.fp, 0u);         // it stands: nothing of it moving
}

// Rule 4, "by its ends" (doc/OBJECTS.md): the same street with the ego at 0.6 x. The car drives
// off at 6 m/s, and in the run's last scans (too few after them for the windowed test), 14-16 m
// ahead, its back (0.17-0.23 m deep) has a column of its side joined in one scan (0.64 m deep) and
// not in the next: the match by its ends, which alone finds it there, holds where the face is a
// face of the deeper object. Scans 37-39 kept 115 of their 419 returns before.
TEST(SimSensors, ACarRecedingAtFiveHundredTwelveColumnsIsHeldByItsBackToTheRunsEnd) {
  auto sc = seenBy(scenario("stop_and_go"), SensorModel::kOs1_64);
  sc.sensor.azimuth_step_deg = 360.0 / 512;
  sc.ego_speed *= 0.6;
  const auto r = runCase(sc);
  std::printf("  scans 37-39: recall %.4f\n", r.frames(37, 40).recall());
  EXPECT_GE(r.frames(37, 40).recall(), 0.9);  // measured 0.990 (0.274 before)
  EXPECT_GE(r.all.precision(), 0.99);         // measured 1.000
}

// Rule 2, "A face apart" (doc/OBJECTS.md): the same street and lidar, the ego at 0.6 x. The car
// drives away 5 m to the side and stops at once at 1.2 s. In scan 12 its rear face (142 returns)
// and its side (81) are two components, the side's first column over a voxel from the corner: the
// side tests moving, the rear, whose place lay inside the car in the scans before, has no moving
// return. Together they are the object scan 11 moved whole, the rear a face of it: it goes too.
TEST(SimSensors, ACarStoppingAtOnceKeepsItsRearFaceApartAtFiveHundredTwelveColumns) {
  auto sc = seenBy(scenario("stop_and_go"), SensorModel::kOs1_64);
  sc.sensor.azimuth_step_deg = 360.0 / 512;
  sc.ego_speed *= 0.6;
  const auto r = runCase(sc);
  EXPECT_GE(r.moverScans("stop_go_car", 12, 13).recall(), 0.9);  // measured 0.996 (0.36 before)
  EXPECT_GE(r.all.precision(), 0.99);                            // measured 1.000
}

// Rule 4, "the same object" (doc/OBJECTS.md): `default` at half speed seen by an OS1-64 at 512
// columns (0.70 degrees). The ego overtakes the cyclist (2 m/s, 8-10 m ahead, 1.2 m to the side)
// in the run's last scans, where the scans after each are too few for the windowed test, and rule
// 4 holds him. From scan 34 it saw his back face alone (0.04 x 0.48 x 1.52 m), his side a column
// beyond, outside the test's cone and the object's voxels; against scan 33's object (0.39 x 0.59
// x 1.59) the face is "smaller" (horizontal diagonal 0.68 of it), and he was lost from there to
// the end: 59 of his 743 returns in scans 34-38, what the windowed test flagged. A face of the
// object is that object, as for rule 4 backwards.
TEST(SimSensors, ACyclistTheEgoOvertakesIsHeldByHisBackFaceAtFiveHundredTwelveColumns) {
  auto sc = seenBy(scenario("default"), SensorModel::kOs1_64);
  sc.sensor.azimuth_step_deg = 360.0 / 512;
  for (auto& m : sc.movers) m.speed *= 0.5;
  const auto r = runCase(sc);
  EXPECT_GE(r.moverScans("cyclist", 34, 39).recall(), 0.8);  // measured 0.939 of 743 (0.079 before)
  // The run's last scan sees his side too (1.81 x 0.54 x 1.59), found by its ends at his back
  // face's: scan 38's object, a face of it, grown more than a voxel deep (doc/OBJECTS.md rule 4,
  // "by its ends").
  EXPECT_GE(r.moverScans("cyclist", 39, 40).recall(), 0.8);  // measured 0.995 of 205 (0 before)
  EXPECT_GE(r.all.precision(), 0.98);                        // measured 0.986 (0.984 before)
}

// doc/OBJECTS.md rule 7, "Seen from about the same side": car_stops_5s' oncoming car (stopping
// 17 m ahead in scan 5, moving by the labels to scan 9) seen by an OS1-64. Rule 7 measures it
// as it stops, and rule 4 backwards carries it back to the run's start from there. Head-on, its
// outline is its front and what its side shows: 30 cells to an HDL-64E (16 of them its side), 13
// at 1024 columns (0.35 degrees), 9-10 at 512, where 20 were asked; and at 512 it has 83-90
// returns, under the 100 of an HDL-64E that rule 7 asked. Scans 0-9 had 303 of their 2,136
// returns moving at 1024 columns (scan 9 alone was measured), 18 of 1,070 at 512.
TEST(SimSensors, ACarThatStopsHeadOnIsMeasuredByItsFrontAtCoarserColumns) {
  for (const double columns : {1024.0, 512.0}) {
    auto sc = seenBy(scenario("car_stops_5s"), SensorModel::kOs1_64);
    sc.sensor.azimuth_step_deg = 360.0 / columns;
    const auto r = runCase(sc);
    const MosCounts driving = r.frames(0, 10);
    std::printf("  %.0f columns: scans 0-9 recall %.3f, precision %.3f\n", columns,
                driving.recall(), r.all.precision());
    EXPECT_GE(driving.recall(), 0.7) << columns;    // measured 0.753 / 0.744 (0.142 / 0.017)
    EXPECT_GE(r.all.precision(), 0.99) << columns;  // measured 1.000 (1.000)
  }
}

// doc/OBJECTS.md rule 7: pedestrian_wall with the ego at 0.6 x its speed, seen by an OS1-64 at
// 512 columns. The wall's far returns, met at 12 degrees, lie 1.5 m apart, and its object (24 m)
// ends where the columns part, a place that moves with the ego. Rule 7 took that end (6 facing
// cells of an outline of 107) for a face across a shift along the wall, measured the wall moving
// in scan 10, and the rules after it took the wall whole in scans 0-14: 64,314 false positives,
// precision 0.020. An outline that is one straight side, shifted along itself, shows no face
// across the shift (its `side` path asks what such a side needs).
TEST(SimSensors, AWallSeenByCoarseColumnsIsNotTakenForAFaceAcrossItsLength) {
  auto sc = seenBy(scenario("pedestrian_wall"), SensorModel::kOs1_64);
  sc.sensor.azimuth_step_deg = 360.0 / 512;
  sc.ego_speed *= 0.6;
  const auto r = runCase(sc);
  std::printf("  precision %.4f, walker recall %.3f\n", r.all.precision(),
              r.per_mover.at("walker").recall());
  EXPECT_GE(r.all.precision(), 0.95);  // measured 0.998 (0.020 before)
}

// DESIGN §2b, grazing beams: ground_curb_ramp (3 scans 0.3 m apart, nothing moving) seen by an
// OS1-64. The ring that meets the parked car's roof (0.23 m under the sensor) 9.7 m ahead meets
// it 0.3 m further from the next scan: its beams pass the roof's returns by 0.3 m, within 2 sigma
// yet each near 0.97 empty, and in a 3-scan window that one vote flagged the ring and, by the
// object rules, the face's corner column (87 returns). They lie in the grazing stretch of the
// roof they end on, and vote nothing now.
TEST(SimSensors, AParkedCarsRoofRingIsStaticToAnOusterInAShortRun) {
  const auto r = runCase(seenBy(scenario("ground_curb_ramp"), SensorModel::kOs1_64));
  std::printf("  static returns flagged: %llu of %llu\n", static_cast<unsigned long long>(r.all.fp),
              static_cast<unsigned long long>(r.all.evaluated()));
  EXPECT_LT(r.all.fp, 9u);  // measured 0 (87 before the hundred-and-fourteenth session)
}

// DESIGN §2b, "Coarse columns' beams spread over their step": an OS1-64 at 512 columns (0.70
// degrees; the cone of lambda_theta 0.60). ground_curb_ramp: the crate on the ramp 19.5 m
// ahead, whose edge column's neighbour passes beside its corner, the column returning from it
// outside the cone (84 static returns flagged before). poles_drift with its walkers at half speed:
// P between two of a walker's columns weighed each by exp(-1.5) or less (recall 0.727 before).
TEST(SimSensors, AnOusterAt512ColumnsSpreadsItsBeamsOverItsColumnStep) {
  auto ramp = seenBy(scenario("ground_curb_ramp"), SensorModel::kOs1_64);
  ramp.sensor.azimuth_step_deg = 360.0 / 512;
  const auto crate = runCase(ramp);
  std::printf("  ground_curb_ramp: %llu static returns flagged\n",
              static_cast<unsigned long long>(crate.all.fp));
  EXPECT_LT(crate.all.fp, 9u);  // measured 0 (84)
  auto walkers = seenBy(scenario("poles_drift"), SensorModel::kOs1_64);
  walkers.sensor.azimuth_step_deg = 360.0 / 512;
  for (auto& m : walkers.movers) m.speed *= 0.5;
  const auto slow = runCase(walkers);
  std::printf("  poles_drift, walkers at half speed: precision %.4f, recall %.4f\n",
              slow.all.precision(), slow.all.recall());
  EXPECT_GE(slow.all.recall(), 0.85);     // measured 0.920 (0.727)
  EXPECT_GE(slow.all.precision(), 0.99);  // measured 1.000 (1.000)
}

// doc/SCAN_CONFLICT.md, "A return at P": queue_stop_go seen by a VLP-16 from its standing ego.
// The queue's first car stops 2.6 m beside the sensor. Its lowest ring is a bottom edge, so the
// beams below P are left out, and the cone holds only beams of that ring returning at P's range:
// e' and o' near 0.5 each, an empty or occupied vote by the noise. Rule 4's tests of the scans
// before or after it alone found the few heads they need (4 points of 2,400) and held the stopped
// car moving for 16 scans (precision 0.855). A scan needs a beam passing P by sigma_m to vote
// empty.
TEST(SimSensors, AQueuesStoppedCarBesideAStandingSixteenRingLidarIsStatic) {
  const auto sc = seenBy(scenario("queue_stop_go"), SensorModel::kVlp16);
  const auto r = runCase(sc);
  EXPECT_GE(r.all.precision(), 0.98);  // measured 0.997 (0.855 before)
  EXPECT_GE(r.all.recall(), 0.95);     // measured 0.973 (0.975)
  // Scans 28-37: the queue stands (static labels) and rule 4 has let go of its farthest car.
  MosCounts stopped;
  for (std::size_t k = 28; k < 38; ++k) stopped += r.per_frame.at(k);
  EXPECT_LE(stopped.fp, 100u);  // measured 0 (2,755-2,772 a scan in 28-36 before)
}

// Rule 4's arrival, "Between two rings" (doc/OBJECTS.md): queue_stop_go seen by an HDL-32E, its
// cars crawling at half speed (1 m/s). The first stands 3.5 m beside the standing ego from scan 20
// (static by the labels from scan 23). A few returns on the edges of its side were moving for the
// scans before it, and the place 0.2 m further in along the side lay between two rings (1.33
// degrees apart, the cone 0.6): no beam there, an unknown mass, which counted as not occupied, and
// rule 4 held the car as arriving in scans 23-24 (7,665 false positives in scan 24). The rings
// around that place return at its range: it was occupied.
TEST(SimSensors, ACrawlingCarStoppedBesideAThirtyTwoRingLidarHasNotArrived) {
  auto sc = seenBy(scenario("queue_stop_go"), SensorModel::kHdl32);
  for (auto& m : sc.movers) m.speed *= 0.5;
  const auto r = runCase(sc);
  std::printf("  scan 24: %llu false positives; all: precision %.4f, recall %.4f\n",
              (unsigned long long)r.frames(24, 25).fp, r.all.precision(), r.all.recall());
  EXPECT_LE(r.frames(24, 25).fp, 1000u);  // measured 312, the van 13 m back (7,977 before)
  EXPECT_GE(r.all.precision(), 0.99);     // measured 0.9954 (0.9796)
  EXPECT_GE(r.all.recall(), 0.98);        // measured 0.9915 (0.9915)
}

// Rule 4's arrival at a large object's ends (doc/OBJECTS.md): truck_crawl seen by an HDL-32E.
// In its last 6 scans too few scans follow to see the truck leave; its new place at the leading
// end, 12-13 of its 23,600 points in two columns, shows it arriving. Every 12th point of the
// whole truck stepped over both columns, and the scans were lost whole (recall 0.915).
TEST(SimSensors, ACrawlingTruckArrivesAtItsLeadingEndToItsLastScan) {
  const auto r = runCase(seenBy(scenario("truck_crawl"), SensorModel::kHdl32));
  EXPECT_GE(r.all.recall(), 0.97);            // measured 0.991 (0.915 before)
  EXPECT_GE(r.all.precision(), 0.99);         // measured 1.000
  EXPECT_GE(r.frames(74, 80).recall(), 0.9);  // measured 1.00 (0 before)
}

// Rules 2 and 4 at a sparse lidar's far face (doc/OBJECTS.md rule 2, "The previous scan's
// object"; rule 4, "in rings"): parked_leaves seen by an HDL-32E, its car receding 15-16.5 m
// ahead in the last four scans. There its back face's lowest ring alone tests moving: in scans
// 56-57 (one component) its face above that foot stayed static, and in 58-59 (the face in two
// pieces, its lowest ring apart, too few scans after to show it leave) the face without that
// ring was under 70 % of the previous object's height, and nothing was held (40 of 157-167
// returns, 0 in scan 59).
TEST(SimSensors, ACarPullingAwayIsHeldToTheLastScanAtThirtyTwoRings) {
  const auto r = runCase(seenBy(scenario("parked_leaves"), SensorModel::kHdl32));
  EXPECT_GE(r.all.recall(), 0.965);           // measured 0.975 (0.952 before)
  EXPECT_GE(r.all.precision(), 0.99);         // measured 0.999
  EXPECT_GE(r.frames(56, 60).recall(), 0.9);  // measured 1.00 (0.19 before)
}

// Rule 4 backwards, "What a scan saw of it" (doc/OBJECTS.md): parked_leaves seen by an OS1-128.
// The car at the kerb stands until 2.5 s (the labels call it moving from scan 21); as the ego
// comes nearer, scan 20 shows more of it (1,854 returns against 1,761-1,767 in scans 21-22), and
// its centroid lay 0.26 m from theirs: the chain carried back from the scans it drove in took
// that for a motion, and scan 20 went moving whole (precision 0.956). Its outline, matched
// against scan 21's, stands.
TEST(SimSensors, AParkedCarShowingMoreOfItselfHasNotMovedAtOneHundredTwentyEightRings) {
  const auto r = runCase(seenBy(scenario("parked_leaves"), SensorModel::kOs1_128));
  std::printf("  scan 20: %llu false positives; all: precision %.4f, recall %.4f\n",
              (unsigned long long)r.frames(20, 21).fp, r.all.precision(), r.all.recall());
  EXPECT_LE(r.frames(20, 21).fp, 100u);
  EXPECT_GE(r.all.precision(), 0.99);
  EXPECT_GE(r.per_mover.at("leaving_car").recall(), 0.95);
}

// Rule 6 at a sparse lidar (doc/OBJECTS.md, "Stacks"): curved_path seen by a VLP-16. Its turning
// car 13-19 m off comes in one slice per ring, 0.5-0.65 m apart. Where one slice moves whole the
// others follow it slice by slice; where none does (scans 26-29, mid-turn), each has about half
// of its returns flagged, and rule 2, which turns each, moved only those (each flat slice is all
// its own foot).
TEST(SimSensors, ATurningCarsSlicesGoTogetherAtSixteenRings) {
  const auto sc = seenBy(scenario("curved_path"), SensorModel::kVlp16);
  const auto r = runCase(sc);
  EXPECT_GE(r.per_mover.at("turning_car").recall(), 0.9);  // measured 0.96 (0.71 before)
  EXPECT_GE(r.all.precision(), 0.99);                      // measured 1.000
  MosCounts mid_turn;
  for (std::size_t k = 26; k < 30; ++k) mid_turn += r.per_frame.at(k);
  EXPECT_GE(mid_turn.recall(), 0.9);  // measured 0.98 (0.61 before)
}

// doc/OBJECTS.md rule 4, "A ring step": curved_path seen by an HDL-32E, its movers at half speed.
// In scan 16 a face of the turning car 21 m off stood 0.54 m high on two rings against the
// previous scan's 1.02 m (a ring step 0.48 m there) and was not taken for that object: 190 of the
// scan's 231 moving returns found. A part on two rings counts a step higher: measured 213 (0.922).
TEST(SimSensors, ATurningCarsFaceARingShorterIsStillItAtThirtyTwoRings) {
  auto sc = seenBy(scenario("curved_path"), SensorModel::kHdl32);
  for (auto& m : sc.movers) m.speed *= 0.5;
  const auto r = runCase(sc);
  std::printf("  scan 16 recall %.3f, turning car %.3f, precision %.3f\n",
              r.per_frame.at(16).recall(), r.per_mover.at("turning_car").recall(),
              r.all.precision());
  EXPECT_GE(r.per_frame.at(16).recall(), 0.88);
  EXPECT_GE(r.all.precision(), 0.99);
}

// Issue #15, MovingTest::ringVote: an HDL-32E's rings lie 1.33 degrees apart against a 0.6-degree
// beam cone, so most window scans hold no beam near a small mover's old place and vote unknown;
// their rings around it vote instead. poles_drift (a walker among thin poles, poses drifting 1 %)
// and pedestrian_wall seen by an HDL-32E, and pedestrian_wall by a VLP-16 (2 degrees apart); the
// poles and the wall stay static.
TEST(SimSensors, SparseLidarsFindSmallMoversBetweenTheirRings) {
  const auto seen_by = [](const char* name, SensorModel m) { return seenBy(scenario(name), m); };
  const auto hdl32 = [&](const char* name) { return seen_by(name, SensorModel::kHdl32); };
  // The ring vote alone (object.ring_pool off, below; rule 6's roofs off too: without the pool
  // the walker comes one slice per ring, and a slice wholly over his moving one goes with it,
  // poles_drift 0.63 -> 0.67 here, 0.47 -> 0.58 without the ring vote). The empty runs (DESIGN
  // §2b) are off too: they find more of the walker (0.71, and 0.57 without the ring vote).
  PipelineParams no_pool, off;
  no_pool.object.ring_pool = 0;
  no_pool.object.roofs = false;
  no_pool.ds.empty_run = 0;
  off.object.ring_pool = 0;
  off.object.roofs = false;
  off.ds.ring_vote = false;
  off.ds.empty_run = 0;
  const auto poles = runCase(hdl32("poles_drift"), no_pool),
             poles_off = runCase(hdl32("poles_drift"), off);
  // measured 0.632 and, without the ring vote, 0.621 (0.63 and 0.47 before rule 4 backwards took
  // a face with or without its side and a mover's rings as one, doc/OBJECTS.md; 0.64 and 0.37
  // before it carried him back at all). The ring vote's own case is pipeline_test's; here it must
  // not cost.
  EXPECT_GE(poles.per_mover.at("walker").recall(), 0.55);
  EXPECT_GE(poles.per_mover.at("walker").recall(), poles_off.per_mover.at("walker").recall());
  EXPECT_GE(poles.all.precision(), 0.97);  // measured 1.000
  const auto wall = runCase(hdl32("pedestrian_wall"), no_pool);
  // The walkers: measured 0.87 and 0.82, precision 0.97 and 0.99 (hundred-and-thirteenth
  // session; when first measured 0.73 and 0.68, and 0.63 and 0.42 without the ring vote).
  EXPECT_GE(wall.per_mover.at("walker").recall(), 0.68);
  EXPECT_GE(wall.all.precision(), 0.95);
  const auto wall16 = runCase(seen_by("pedestrian_wall", SensorModel::kVlp16), no_pool);
  EXPECT_GE(wall16.per_mover.at("walker").recall(), 0.62);
  EXPECT_GE(wall16.all.precision(), 0.95);
  // object.ring_pool (doc/OBJECTS.md rule 1; 1 m, the default): the walker at 22-30 m is one
  // slice per ring, each under min_moving (7), and the object rules called every slice noise;
  // joined across the rings he is one object.
  const auto poles_pool = runCase(hdl32("poles_drift"));
  EXPECT_GE(poles_pool.per_mover.at("walker").recall(), 0.9);  // measured 0.973
  EXPECT_GE(poles_pool.all.precision(), 0.97);                 // measured 1.000
}

// The mounting is measured, not assumed: each scan's estimate lies within 0.1 m of the truth
// (VLP-16 at 2.5 m sees the road only beyond 9 m, between parked cars: 0.15 m).
TEST(SimSensors, GroundBelowTheSensorIsMeasuredInEveryScan) {
  for (const SensorModel m : {SensorModel::kVlp16, SensorModel::kHdl64, SensorModel::kOs1_128})
    for (const double h : {0.8, 1.73, 2.5}) {
      const auto sc = sensorScene(m, h);
      for (int k = 0; k < sc.frames; k += 7) {
        const auto g = estimateGroundHeight(sim::simulateScan(sc, k, 2).points);
        ASSERT_TRUE(g) << sc.name << " frame " << k;
        EXPECT_NEAR(-*g, h, m == SensorModel::kVlp16 && h > 2 ? 0.15 : 0.1)
            << sc.name << " frame " << k;
      }
    }
}

// Issue #15: a lidar tilted on its vehicle (pitched 10 degrees down and rolled 4, as on robots
// that look at the ground ahead) is levelled by its mount (Frame::mount, a rawlog's sensorPose)
// before the ground stage; the same rays, in the tilted sensor's frame.
TEST(SimSensors, TiltedMountIsLevelledByItsSensorPose) {
  const auto sc = sensorScene(SensorModel::kHdl64, 1.73);
  const double ref = runCase(sc).all.iou();
  const Eigen::Matrix3d mount =
      (Eigen::AngleAxisd(0.07, Eigen::Vector3d::UnitX()) *  // roll, then pitch nose down
       Eigen::AngleAxisd(0.17, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  const double tilted =
      runCase(sc, PipelineParams{}, nullptr, nullptr, false, false, &mount).all.iou();
  EXPECT_GE(tilted, ref - 0.03) << "level: IoU " << ref;
}

// DESIGN §2.0 and §2f: with de-skewing, a chunk's first scan has no predecessor and takes the
// motion to its second scan, the whole run's the motion from its predecessor (with drifting poses
// the two differ). It is not owned, and the scans the chunk owns keep the whole run's labels: on a
// curve at 14 m/s with sweep motion, chunks started 2K scans before their first owned epoch and
// K + 1 scans before it.
TEST(SimCases, ChunksWithDeskewReproduceTheWholeRun) {
  auto sc = scenario("curved_path");
  sc.frames = 30;
  sc.ego_speed = 14;
  sc.sensor.sweep_motion = true;
  sc.sensor.camera = false;
  sc.ego_pose_drift = 0.05;
  PipelineParams p;
  p.ds.window_k = 5;
  p.epoch = 10;
  std::vector<Frame> frames;
  for (int k = 0; k < sc.frames; ++k)
    frames.push_back(sim::frameOf(sim::simulateScan(sc, k, 2), k));
  struct Run {
    std::map<long, Labels> labels;
    std::map<long, double> shift;
  };
  auto run = [&](int first) {
    Run out;
    LaserPipeline pl(p, [&](ScanResult&& r) {
      out.labels[static_cast<long>(r.index)] = r.labels;
      if (r.stats.deskewed) out.shift[static_cast<long>(r.index)] = r.stats.deskew_max_shift;
    });
    for (int k = first; k < sc.frames; ++k) pl.push(Frame(frames[static_cast<std::size_t>(k)]));
    pl.finish();
    return out;
  };
  const Run whole = run(0);
  ASSERT_EQ(whole.shift.size(), 30u);
  for (const int first : {10, 14}) {
    const Run chunk = run(first);
    ASSERT_EQ(chunk.shift.size(), static_cast<std::size_t>(sc.frames - first));
    EXPECT_NE(chunk.shift.at(first), whole.shift.at(first)) << "start " << first;
    EXPECT_EQ(chunk.shift.at(first + 1), whole.shift.at(first + 1)) << "start " << first;
    for (long s = 20; s < sc.frames; ++s)
      EXPECT_TRUE(chunk.labels.at(s) == whole.labels.at(s)) << "start " << first << ", scan " << s;
  }
}
