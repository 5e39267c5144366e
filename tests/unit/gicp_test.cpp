// SPDX-License-Identifier: BSD-3-Clause
// GICP (DESIGN §2.1): known rigid transforms recovered from perturbed guesses, both ways, on a
// synthetic street sampled twice with different point sets; degenerate scenes refused clearly.
#include <gtest/gtest.h>

#include <functional>
#include <random>
#include <unordered_map>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/registration/gicp.h"
#include "cleanmap/registration/odometry.h"
#include "test_data.h"

using namespace cleanmap;
using namespace cleanmap::reg;

namespace {

// Surface samples of a street in the world frame: road, two facades with recesses, parked boxes,
// poles. `seed` draws the sample positions, so two calls sample the same surfaces differently.
std::vector<Eigen::Vector3d> street(uint64_t seed, bool plane_only = false) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<Eigen::Vector3d> pts;
  auto add = [&](const Eigen::Vector3d& p) {
    pts.push_back(p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  };
  for (int i = 0; i < 40000; ++i) add({-30 + 60 * u(rng), -10 + 20 * u(rng), -1.7});  // road
  if (plane_only) return pts;
  for (int side : {-1, 1})
    for (int i = 0; i < 15000; ++i) {  // facades with 1 m recesses every 6 m
      const double x = -30 + 60 * u(rng), z = -1.7 + 8 * u(rng);
      const double y = side * (std::fmod(x + 30, 6.0) < 3.0 ? 10.0 : 11.0);
      add({x, y, z});
    }
  const double boxes[][2] = {{-12, 5}, {-4, -6}, {6, 5.5}, {15, -5}, {22, 4}};
  for (const auto& b : boxes)
    for (int i = 0; i < 3000; ++i) {  // 4 x 2 x 1.5 m boxes: the sides and the top
      const int face = i % 5;
      const double a = u(rng), c = u(rng);
      Eigen::Vector3d q;
      if (face == 0)
        q = {b[0] + 4 * a, b[1], -1.7 + 1.5 * c};
      else if (face == 1)
        q = {b[0] + 4 * a, b[1] + 2, -1.7 + 1.5 * c};
      else if (face == 2)
        q = {b[0], b[1] + 2 * a, -1.7 + 1.5 * c};
      else if (face == 3)
        q = {b[0] + 4, b[1] + 2 * a, -1.7 + 1.5 * c};
      else
        q = {b[0] + 4 * a, b[1] + 2 * c, -0.2};
      add(q);
    }
  for (double x = -25; x < 30; x += 7)
    for (int i = 0; i < 400; ++i) {  // poles, radius 0.1 m
      const double t = 2 * M_PI * u(rng);
      add({x + 0.1 * std::cos(t), 8 + 0.1 * std::sin(t), -1.7 + 4 * u(rng)});
    }
  return pts;
}

CovCloud cloudOf(const std::vector<Eigen::Vector3d>& pts, const Eigen::Isometry3d& T_frame_world) {
  CovCloud c;
  for (const uint32_t k : voxelDownsample(pts, 0.3)) c.points.push_back(T_frame_world * pts[k]);
  c.covs = planeCovariances(c.points, 10, 1.0, 1e-3, 2);
  return c;
}

VoxelMap mapOf(const CovCloud& c) {
  VoxelMap m(1.0, 20);
  m.insert(c, 0);
  return m;
}

Eigen::Isometry3d pose(double x, double y, double z, double yaw, double pitch, double roll) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// `world` seen from the sensor pose T (points in the sensor frame), 1 cm of seeded noise per axis.
std::vector<PointXYZI> scanFrom(const std::vector<Eigen::Vector3d>& world,
                                const Eigen::Isometry3d& T, uint64_t seed) {
  std::vector<PointXYZI> s;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  const Eigen::Isometry3d inv = T.inverse();
  for (const auto& p : world) {
    const Eigen::Vector3d q = inv * p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    s.push_back({float(q.x()), float(q.y()), float(q.z()), 0});
  }
  return s;
}

// A corridor (road and plain facades: nothing holds the step along the road) seen from x_sensor on
// its axis, 1 cm of seeded noise across; `more(add, u)` adds the scene's other surfaces, world
// points through `add`, with uniform draws from `u`.
using AddPoint = std::function<void(const Eigen::Vector3d&)>;
using Uniform = std::function<double()>;
std::vector<PointXYZI> corridorScan(
    double x_sensor, uint64_t seed,
    const std::function<void(const AddPoint&, const Uniform&)>& more) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<PointXYZI> s;
  const AddPoint add = [&](const Eigen::Vector3d& w) {
    const Eigen::Vector3d q =
        w - Eigen::Vector3d(x_sensor, 0, 0) + Eigen::Vector3d(noise(rng), noise(rng), 0);
    s.push_back({float(q.x()), float(q.y()), float(q.z()), 0});
  };
  const Uniform u = [&] { return uniform(rng); };
  for (int i = 0; i < 30000; ++i) add({-30 + 60 * u(), -10 + 20 * u(), -1.7});  // road
  for (int side : {-1, 1})
    for (int i = 0; i < 12000; ++i) add({-30 + 60 * u(), side * 10.0, -1.7 + 8 * u()});
  more(add, u);
  return s;
}

double degrees(const Eigen::Isometry3d& E) {
  return Eigen::AngleAxisd(E.linear()).angle() * 180.0 / M_PI;
}

}  // namespace

TEST(Gicp, RecoversKnownTransformsFromPerturbedGuesses) {
  const Eigen::Isometry3d truth = pose(1.3, -0.4, 0.05, 0.08, 0.01, -0.015);  // sensor -> world
  const VoxelMap target = mapOf(cloudOf(street(1), Eigen::Isometry3d::Identity()));
  const CovCloud source = cloudOf(street(2), truth.inverse());  // the street seen from `truth`
  GicpParams p;
  const Eigen::Isometry3d perturbations[] = {
      Eigen::Isometry3d::Identity(), pose(0.3, 0, 0, 0, 0, 0), pose(-0.2, 0.25, 0.05, 0.03, 0, 0),
      pose(0.1, -0.2, -0.05, -0.035, 0.01, 0.01), pose(0, 0, 0, 0.02, -0.01, 0.01)};
  for (const auto& d : perturbations) {
    const GicpResult r = alignGicp(source, target, truth * d, p, 2);
    ASSERT_TRUE(r.failure.empty()) << r.failure;
    const Eigen::Isometry3d err = truth.inverse() * r.T;
    EXPECT_LE(err.translation().norm(), 0.01)
        << "from guess offset " << d.translation().transpose();
    EXPECT_LE(degrees(err), 0.05);
    EXPECT_TRUE(r.converged);
    EXPECT_GT(r.fitness, 0.9);
  }
  // The inverse problem: the first street aligned to the second.
  const VoxelMap target2 = mapOf(cloudOf(street(2), truth.inverse()));
  const CovCloud source2 = cloudOf(street(1), Eigen::Isometry3d::Identity());
  const GicpResult r =
      alignGicp(source2, target2, truth.inverse() * pose(0.2, 0.1, 0, 0.02, 0, 0), p, 2);
  ASSERT_TRUE(r.failure.empty()) << r.failure;
  const Eigen::Isometry3d err = truth * r.T;
  EXPECT_LE(err.translation().norm(), 0.01);
  EXPECT_LE(degrees(err), 0.05);
}

TEST(Gicp, SameResultWhateverTheThreadCount) {
  const Eigen::Isometry3d truth = pose(0.8, 0.2, 0, 0.05, 0, 0);
  const VoxelMap target = mapOf(cloudOf(street(3), Eigen::Isometry3d::Identity()));
  const CovCloud source = cloudOf(street(4), truth.inverse());
  const GicpResult a = alignGicp(source, target, Eigen::Isometry3d::Identity(), GicpParams{}, 1);
  const GicpResult b = alignGicp(source, target, Eigen::Isometry3d::Identity(), GicpParams{}, 3);
  EXPECT_TRUE(a.T.matrix() == b.T.matrix());
  EXPECT_EQ(a.iterations, b.iterations);
}

TEST(Gicp, DegenerateInputsFailClearly) {
  GicpParams p;
  const VoxelMap target = mapOf(cloudOf(street(5), Eigen::Isometry3d::Identity()));
  CovCloud few;
  few.points.assign(10, Eigen::Vector3d(1, 2, 3));
  few.covs.assign(10, Eigen::Matrix3d::Identity());
  const GicpResult f = alignGicp(few, target, Eigen::Isometry3d::Identity(), p, 2);
  EXPECT_NE(f.failure.find("too few points (10)"), std::string::npos) << f.failure;
  EXPECT_EQ(f.reason, "too few points");  // what reports count refusals by
  EXPECT_FALSE(f.no_overlap);
  // A road alone: the translation along it (and across) is not observable.
  const VoxelMap road = mapOf(cloudOf(street(6, true), Eigen::Isometry3d::Identity()));
  const GicpResult r = alignGicp(cloudOf(street(7, true), Eigen::Isometry3d::Identity()), road,
                                 pose(0.3, 0, 0, 0, 0, 0), p, 2);
  EXPECT_TRUE(r.degenerate);
  EXPECT_NE(r.failure.find("degenerate"), std::string::npos) << r.failure;
  EXPECT_EQ(r.reason, "degenerate scene");
  // Nothing near: no correspondences.
  const GicpResult far = alignGicp(cloudOf(street(8), pose(500, 0, 0, 0, 0, 0)), target,
                                   Eigen::Isometry3d::Identity(), p, 2);
  EXPECT_NE(far.failure.find("too few correspondences"), std::string::npos) << far.failure;
  EXPECT_EQ(far.reason, "too few correspondences");
  EXPECT_TRUE(far.no_overlap);
}

// DESIGN §2.1 "Starting at speed": the fit of the surfaces that face the forward axis (the boxes'
// ends, the facades' recesses) tells a scan 1 m along the street from a standstill; the road alone
// has no such surface.
TEST(Gicp, FacingScoreTellsWhereAlongTheStreet) {
  const VoxelMap target = mapOf(cloudOf(street(1), Eigen::Isometry3d::Identity()));
  const Eigen::Isometry3d truth = pose(0.8, 0, 0, 0, 0, 0);
  const CovCloud source = cloudOf(street(2), truth.inverse());
  const Eigen::Vector3d forward = Eigen::Vector3d::UnitX();
  GicpParams p;
  const auto at_truth = facingScore(source, target, truth, forward, p, 2, 20);
  const auto standing =
      facingScore(source, target, Eigen::Isometry3d::Identity(), forward, p, 2, 20);
  ASSERT_TRUE(at_truth && standing);
  EXPECT_GT(*at_truth, 0.5);
  EXPECT_GT(*at_truth, *standing + 0.3);
  const VoxelMap road = mapOf(cloudOf(street(6, true), Eigen::Isometry3d::Identity()));
  EXPECT_FALSE(facingScore(cloudOf(street(7, true), Eigen::Isometry3d::Identity()), road,
                           Eigen::Isometry3d::Identity(), forward, p, 2, 20));
}

TEST(Odometry, TracksAConstantMotionAndRefusesJumps) {
  RegistrationParams rp;
  Odometry odo(rp, 2);
  const auto world = street(9);
  auto scanAt = [&](const Eigen::Isometry3d& T, uint64_t seed) { return scanFrom(world, T, seed); };
  for (int k = 0; k < 6; ++k) {
    const Eigen::Isometry3d truth = pose(0.8 * k, 0.05 * k, 0, 0.01 * k, 0, 0);  // 8 m/s at 10 Hz
    const OdometryStep s = odo.track(scanAt(truth, 100 + uint64_t(k)), 0.1 * k, k);
    EXPECT_TRUE(s.accepted) << s.status;
    EXPECT_EQ(s.reason, "") << "scan " << k;  // an accepted scan has no refusal reason
    const Eigen::Isometry3d err = truth.inverse() * s.pose;
    EXPECT_LE(err.translation().norm(), 0.02) << "scan " << k;
    EXPECT_LE(degrees(err), 0.05) << "scan " << k;
  }
  // A scan 30 m away 0.1 s later is not a car's motion: refused, the prediction kept.
  const OdometryStep j =
      odo.track(scanAt(pose(34, 0, 0, 0, 0, 0), 7), 0.6, 6, pose(34, 0, 0, 0, 0, 0));
  EXPECT_FALSE(j.accepted);
  EXPECT_NE(j.status.find("jump"), std::string::npos) << j.status;
  EXPECT_EQ(j.reason, "a jump beyond max_speed / max_turn_rate");
}

// DESIGN §2.1 step 4: scans GICP refuses (here a stretch of bare road, degenerate) get the motion
// model's guess, and the model goes on from those guesses: the sensor keeps its velocity through
// the stretch (it stopped 5 steps in when only accepted scans fed the model), and the street
// after it is aligned from a guess near the truth.
// DESIGN §2.1 "Starting at speed" on kitti_highway's first two scans, the first anchored at its
// given pose: the second's standstill fits too few surfaces facing the forward axis, so the 20
// guesses run, each screened with 8 GICP iterations, and only the best goes on (issue #16;
// unscreened they ran 471 iterations). The pose kept is the given one within centimetres.
TEST(Odometry, ScreensItsStartGuessesOnARealStart) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  RegistrationParams rp;
  Odometry odo(rp, 2);
  const Frame f0 = seq.frame(0), f1 = seq.frame(1);
  ASSERT_TRUE(f0.scan.has_pose && f1.scan.has_pose);
  EXPECT_TRUE(odo.track(f0.scan.points, f0.scan.timestamp, 0, f0.scan.pose).accepted);
  const OdometryStep s = odo.track(f1.scan.points, f1.scan.timestamp, 1);
  EXPECT_EQ(s.start_guesses, 20);
  EXPECT_LE(s.guess_iterations, 8 * s.start_guesses + rp.max_iterations);
  EXPECT_TRUE(s.accepted) << s.status;
  const double error = (s.pose.translation() - f1.scan.pose.translation()).norm();
  std::printf("  kitti_highway scan 1: %d guesses, %d iterations, %.4f m from the given pose\n",
              s.start_guesses, s.guess_iterations, error);
  EXPECT_LT(error, 0.05);
}

TEST(Odometry, KeepsItsVelocityThroughScansItCannotAlign) {
  RegistrationParams rp;
  Odometry odo(rp, 2);
  const auto world = street(9), road = street(10, true);
  auto scanAt = [&](const std::vector<Eigen::Vector3d>& pts, double x, uint64_t seed) {
    return scanFrom(pts, pose(x, 0, 0, 0, 0, 0), seed);
  };
  constexpr double kStep = 0.5;  // m per scan, 5 m/s
  for (int k = 0; k < 18; ++k) {
    const bool bare = k >= 4 && k < 14;  // scans 4-13: the road alone
    const OdometryStep s =
        odo.track(scanAt(bare ? road : world, kStep * k, 200 + uint64_t(k)), 0.1 * k, k);
    EXPECT_EQ(s.accepted, !bare) << "scan " << k << ": " << s.status;
    if (bare) {
      EXPECT_NE(s.status.find("degenerate"), std::string::npos) << s.status;
    }
    EXPECT_NEAR(s.pose.translation().x(), kStep * k, bare ? 0.02 * kStep * k : 0.02)
        << "scan " << k << ": " << s.status;
  }
}

// DESIGN §2.1 step 4: after a long gap (4 s without returns at 20 m/s) the scans hold nothing the
// map holds. The first two of them are refused and the map starts again at the next, from the
// motion model's guess, so the odometry tracks again (refused for good when the map was kept).
// One odd scan that overlaps nothing (scan 3) is refused and the map kept.
TEST(Odometry, StartsTheMapAgainWhereItNoLongerOverlapsTheScans) {
  RegistrationParams rp;
  Odometry odo(rp, 2);
  const auto before = street(11);
  auto after = street(12);
  for (auto& p : after) p.x() += 100;  // another street, 100 m on
  auto scanAt = [&](const std::vector<Eigen::Vector3d>& pts, double x, uint64_t seed) {
    return scanFrom(pts, pose(x, 0, 0, 0, 0, 0), seed);
  };
  constexpr double kStep = 2.0;  // m per scan, 20 m/s
  double restart = 0;
  for (int k = 0; k < 56; ++k) {
    const double x = kStep * k;
    const std::vector<PointXYZI> pts = k == 3   ? scanAt(after, x, 400 + uint64_t(k))
                                       : k < 6  ? scanAt(before, x, 400 + uint64_t(k))
                                       : k < 44 ? std::vector<PointXYZI>{}
                                                : scanAt(after, x, 400 + uint64_t(k));
    // Scan 1 starts from its true pose (as from input odometry): the model starts at 20 m/s.
    const OdometryStep s =
        odo.track(pts, 0.1 * k, k, k < 2 ? std::optional(pose(x, 0, 0, 0, 0, 0)) : std::nullopt);
    if (k == 3) {
      EXPECT_FALSE(s.accepted);
      EXPECT_EQ(s.status.find("the map starts again"), std::string::npos) << s.status;
    } else if (k < 6) {
      EXPECT_EQ(s.status, k == 0 ? "first" : "ok") << "scan " << k;  // the map kept
    }
    if (k < 44) continue;
    if (k < 46) {
      EXPECT_FALSE(s.accepted);
      EXPECT_NE(s.status.find("too few correspondences"), std::string::npos) << s.status;
      EXPECT_EQ(s.status.find("the map starts again") != std::string::npos, k == 45) << s.status;
      EXPECT_EQ(s.reason, "too few correspondences");
      EXPECT_EQ(s.map_restarts, k == 45);
    } else {
      EXPECT_EQ(s.status, k == 46 ? "first" : "ok") << "scan " << k;
    }
    // The guess drifted by what the model's speed was off, 4 s long; past the new start, the
    // alignment holds each step.
    EXPECT_NEAR(s.pose.translation().x(), x, 0.1) << "scan " << k << ": " << s.status;
    if (k == 46) restart = s.pose.translation().x();
    if (k > 46) {
      EXPECT_NEAR(s.pose.translation().x() - restart, x - 92, 0.02) << "scan " << k;
    }
  }
}

// DESIGN §2.1 step 4: with input odometry, an alignment held by a truck driving ahead at the
// sensor's speed in a corridor (the only hold along the road) is refused where it strays from the
// odometry's guess, and the odometry kept; a given pose as the guess only starts GICP.
TEST(Odometry, InputOdometryBoundsTheAlignment) {
  constexpr double kStep = 0.8;  // m per scan, 8 m/s
  auto scanAt = [&](int k, uint64_t seed) {
    return corridorScan(kStep * k, seed, [&](const AddPoint& add, const Uniform& u) {
      for (int i = 0; i < 4000; ++i) {  // the truck's back and sides, 6 m ahead, moving along
        const double x0 = 6 + kStep * k, a = u(), c = u();
        if (i % 3 == 0)
          add({x0, -1.25 + 2.5 * a, -1.2 + 3.5 * c});
        else
          add({x0 + 8 * a, i % 3 == 1 ? -1.25 : 1.25, -1.2 + 3.5 * c});
      }
    });
  };
  // Scans 0 and 1, the guess the true pose (exact odometry, or a given pose).
  auto run = [&](Prior kind) {
    Odometry odo(RegistrationParams{}, 2);
    odo.track(scanAt(0, 500), 0.0, 0, pose(0, 0, 0, 0, 0, 0), kind);
    return odo.track(scanAt(1, 501), 0.1, 1, pose(kStep, 0, 0, 0, 0, 0), kind);
  };
  const OdometryStep odo = run(Prior::kOdometry), given = run(Prior::kGiven);
  std::printf("  one step of %.1f m: odometry guess %.3f m (%s), given guess %.3f m (%s)\n", kStep,
              odo.pose.translation().x(), odo.status.c_str(), given.pose.translation().x(),
              given.status.c_str());
  EXPECT_FALSE(odo.accepted);
  EXPECT_NE(odo.status.find("disagrees with the odometry"), std::string::npos) << odo.status;
  EXPECT_EQ(odo.reason, "disagrees with the odometry");
  EXPECT_NEAR(odo.pose.translation().x(), kStep, 1e-9);
  EXPECT_TRUE(given.accepted) << given.status;
  EXPECT_LT(given.pose.translation().x(), 0.5 * kStep);  // the truck holds it near the first pose
}

// DESIGN §2.1 step 4, over the window: the scans move 0.16 m a scan, the odometry says 0.10 (as
// traffic or a corridor holding GICP a few centimetres a scan off would look to the check). Each
// step strays 6 cm from the odometry's guess, under the 0.2 m tolerance; over the scans before it
// the estimate strays farther than the odometry errs (0.2 m + 5 % of its path), and is refused
// from the fourth scan on. With odometry_window 1 (the check per step only) every scan is
// accepted and the estimate leaves the odometry by 6 cm a scan.
TEST(Odometry, InputOdometryBoundsTheDriftOverItsWindow) {
  constexpr double kScan = 0.16, kWheels = 0.10;  // m per scan
  const auto world = street(900);
  // `blind`: a scan without odometry (the constant-velocity guess), which breaks its chain.
  auto run = [&](int window, int blind = -1) {
    RegistrationParams p;
    p.odometry_window = window;
    Odometry odo(p, 2);
    std::vector<OdometryStep> steps;
    Eigen::Isometry3d prev = Eigen::Isometry3d::Identity();
    for (int k = 0; k < 12; ++k) {
      // The guess: the previous estimate moved by the odometry's increment.
      const Eigen::Isometry3d guess = k == 0 ? prev : prev * pose(kWheels, 0, 0, 0, 0, 0);
      const auto scan = scanFrom(world, pose(kScan * k, 0, 0, 0, 0, 0), 900 + k);
      steps.push_back(k == blind ? odo.track(scan, 0.1 * k, k)
                                 : odo.track(scan, 0.1 * k, k, guess, Prior::kOdometry));
      prev = steps.back().pose;
    }
    return steps;
  };
  const auto per_step = run(1), windowed = run(RegistrationParams{}.odometry_window);
  for (int k = 1; k < 12; ++k) {
    EXPECT_TRUE(per_step[k].accepted) << "scan " << k << ": " << per_step[k].status;
    EXPECT_NEAR(per_step[k].pose.translation().x(), kScan * k, 0.02) << "scan " << k;
  }
  int first_refused = -1;
  for (int k = 1; k < 12; ++k) {
    if (first_refused < 0 && !windowed[k].accepted) first_refused = k;
    // Between any two scans of the window the estimate keeps within what the odometry errs.
    for (int j = std::max(0, k - 10); j < k; ++j) {
      const double est = windowed[k].pose.translation().x() - windowed[j].pose.translation().x();
      const double odo = kWheels * (k - j);
      EXPECT_LE(std::abs(est - odo), 0.2 + 0.05 * odo + 1e-9) << "scans " << j << ", " << k;
    }
  }
  std::printf("  first refused: scan %d (%s)\n", first_refused,
              first_refused > 0 ? windowed[first_refused].status.c_str() : "");
  EXPECT_EQ(first_refused, 4);
  EXPECT_EQ(windowed[first_refused].reason, "disagrees with the odometry");
  // Scan 3 without odometry: the chain starts again at its estimate, so the window reaches back
  // to scan 3 only and the first refusal comes four scans later.
  const auto broken = run(RegistrationParams{}.odometry_window, 3);
  int first_after_break = -1;
  for (int k = 1; k < 12 && first_after_break < 0; ++k)
    if (!broken[k].accepted) first_after_break = k;
  EXPECT_TRUE(broken[3].accepted) << broken[3].status;
  EXPECT_EQ(first_after_break, 7) << (first_after_break > 0 ? broken[first_after_break].status
                                                            : "");
}

// DESIGN §2.1, "Traffic that moves with the sensor": a corridor held along the road by a wall far
// ahead and a row of poles, beside three trucks driving at the sensor's speed. The trucks sit in
// the sensor frame where they were one scan before, so aligned against the newest map entries
// (map_lag 0) they pull each step short; with map_lag 1 their entries are two steps (0.5 m)
// behind them, where the robust weight is a fifth of one step's, and the static scene decides.
TEST(Odometry, MapLagKeepsTrafficMovingWithTheSensorFromDraggingIt) {
  constexpr double kStep = 0.25;  // m per scan, 2.5 m/s
  auto scanAt = [&](int k, uint64_t seed) {
    return corridorScan(kStep * k, seed, [&](const AddPoint& add, const Uniform& u) {
      for (int i = 0; i < 500; ++i)  // a wall across the road ahead: what holds the step
        add({28.0, -10 + 20 * u(), -1.7 + 8 * u()});
      for (double x = -24; x < 30; x += 9)
        for (int i = 0; i < 300; ++i) {  // poles
          const double t = 2 * M_PI * u();
          add({x + 0.1 * std::cos(t), 8 + 0.1 * std::sin(t), -1.7 + 4 * u()});
        }
      const double trucks[][2] = {{4, -4.5}, {-14, 3}, {12, 3}};  // rear x, right side y
      for (const auto& t : trucks)
        for (int i = 0; i < 2000; ++i) {  // 8 x 2.5 x 3.5 m boxes moving with the sensor
          const double x0 = t[0] + kStep * k, a = u(), c = u();
          switch (i % 5) {
            case 0:
              add({x0 + 8 * a, t[1], -1.2 + 3.5 * c});
              break;
            case 1:
              add({x0 + 8 * a, t[1] + 2.5, -1.2 + 3.5 * c});
              break;
            case 2:
              add({x0, t[1] + 2.5 * a, -1.2 + 3.5 * c});
              break;
            case 3:
              add({x0 + 8, t[1] + 2.5 * a, -1.2 + 3.5 * c});
              break;
            default:
              add({x0 + 8 * a, t[1] + 2.5 * c, 2.3});
          }
        }
    });
  };
  auto run = [&](int lag) {
    RegistrationParams rp;
    rp.map_lag = lag;
    Odometry odo(rp, 2);
    double x = 0;
    for (int k = 0; k < 16; ++k) {
      // Scan 1 starts from its true pose (as from input odometry), so the motion model starts
      // from the true speed; then constant velocity.
      const OdometryStep s =
          odo.track(scanAt(k, 300 + uint64_t(k)), 0.1 * k, k,
                    k < 2 ? std::optional(pose(kStep * k, 0, 0, 0, 0, 0)) : std::nullopt);
      EXPECT_TRUE(s.accepted) << "map_lag " << lag << ", scan " << k << ": " << s.status;
      x = s.pose.translation().x();
    }
    return x;
  };
  const double truth = 15 * kStep, lagged = run(1), every = run(0);
  std::printf("  15 scans, %.2f m: map_lag 1 %.3f m, map_lag 0 %.3f m\n", truth, lagged, every);
  EXPECT_NEAR(lagged, truth, 0.03 * truth);  // measured 2.2 % short
  EXPECT_LT(every, 0.96 * truth);            // the drag map_lag removes (measured 4.9 % short)
}

// The odometry's per-scan voxel set grows past what it reserves (a scan's points / 8 voxels): a
// registration.voxel below the points' spacing gives about a voxel a point (0.15 m here: 56,575
// voxels a scan, against the 32,768 slots of the earlier table, which did not grow, filled up, and
// never returned). Two scans are still aligned.
TEST(Odometry, TracksWithAVoxelBelowThePointSpacing) {
  RegistrationParams rp;
  rp.voxel = 0.15;
  Odometry odo(rp, 2);
  const auto world = street(9);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Isometry3d truth = pose(0.8 * k, 0, 0, 0.01 * k, 0, 0);
    const OdometryStep s = odo.track(scanFrom(world, truth, 200 + uint64_t(k)), 0.1 * k, k);
    EXPECT_TRUE(s.accepted) << s.status;
    EXPECT_LE((truth.inverse() * s.pose).translation().norm(), 0.02) << "scan " << k;
  }
}

// The local map against a brute-force search over the entries it should still hold, after a
// scan's flagged points are taken out (Odometry::dropPoints) and far voxels are forgotten: the
// nearest entry within max_dist, and the count.
TEST(VoxelMap, NearestMatchesBruteForceAfterRemovalsAndPruning) {
  constexpr double kVoxel = 1.0;
  VoxelMap map(kVoxel, 1000);  // room for every point: the brute force needs no per-voxel cap
  struct Entry {
    Eigen::Vector3d p;
    int64_t scan;
    uint32_t point;
  };
  std::vector<Entry> all;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  for (int64_t scan = 0; scan < 4; ++scan) {
    CovCloud c;
    for (uint32_t i = 0; i < 3000; ++i) {
      c.points.push_back({u(rng), u(rng), 0.1 * u(rng)});
      c.covs.push_back(Eigen::Matrix3d::Identity());
      all.push_back({c.points.back(), scan, i});
    }
    map.insert(c, scan);
  }
  ASSERT_EQ(map.size(), all.size());
  std::vector<uint8_t> drop(3000, 0);
  for (std::size_t i = 0; i < drop.size(); i += 3) drop[i] = 1;  // scan 2's moving points
  map.remove(2, drop);
  // Forget the voxels whose first entry lies beyond 15 m of (5, 0, 0), as VoxelMap::prune does.
  const Eigen::Vector3d centre(5, 0, 0);
  map.prune(centre, 15.0);
  auto key = [](const Eigen::Vector3d& p) { return cellKeyOf(p.x(), p.y(), p.z(), 1.0 / kVoxel); };
  std::vector<Entry> left;
  for (const Entry& e : all)
    if (!(e.scan == 2 && drop[e.point])) left.push_back(e);
  std::unordered_map<uint64_t, Eigen::Vector3d> first;  // each voxel's first entry left
  for (const Entry& e : left) first.emplace(key(e.p), e.p);
  std::vector<Entry> kept;
  for (const Entry& e : left)
    if ((first.at(key(e.p)) - centre).squaredNorm() <= 15.0 * 15.0) kept.push_back(e);
  EXPECT_EQ(map.size(), kept.size());
  ASSERT_GT(kept.size(), 1000u);
  ASSERT_LT(kept.size(), left.size());
  // Every entry, and (registration.map_lag) only those of scans up to 1 or up to 2.
  for (const int64_t newest : {INT64_MAX, int64_t(1), int64_t(2)})
    for (int q = 0; q < 2000; ++q) {
      const Eigen::Vector3d p(u(rng), u(rng), 0.1 * u(rng));
      double best = 0.8 * 0.8;  // max_dist 0.8 m
      bool any = false;
      for (const auto& k : kept)
        if (k.scan <= newest && (k.p - p).squaredNorm() < best)
          best = (k.p - p).squaredNorm(), any = true;
      const VoxelMap::Match m = map.nearest(p, 0.8, newest);
      ASSERT_EQ(bool(m), any) << "query " << q << ", scans up to " << newest;
      if (any) {
        EXPECT_EQ((*m.p - p).squaredNorm(), best) << "query " << q << ", scans up to " << newest;
      }
    }
  // Scans come in order (a voxel's entries stay in scan order): an earlier one is refused.
  CovCloud late;
  late.points.push_back({0, 0, 0});
  late.covs.push_back(Eigen::Matrix3d::Identity());
  EXPECT_THROW(map.insert(late, 2), std::invalid_argument);
}
