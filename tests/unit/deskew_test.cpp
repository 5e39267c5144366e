// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.0: the de-skew of a sweep taken while the sensor moves.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "cleanmap/core/deskew.h"
#include "cleanmap/core/params.h"

namespace cleanmap {
namespace {

// A car on a curve: 14 m/s forward, turning at 0.5 rad/s, its exact pose t seconds after the
// reference (constant body velocity: an arc).
Eigen::Isometry3d arcPose(double t) {
  const double v = 14.0, w = 0.5;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(w * t, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() =
      Eigen::Vector3d(v / w * std::sin(w * t), v / w * (1 - std::cos(w * t)), 0.1 * t);
  return T;
}

// The sweep of a lidar on that car inside a round courtyard (a wall of radius 25 m around the
// origin, 4 m high): columns clockwise from the rear over 0.1 s, the timestamp facing forward
// (t = 0). Returns the sensor-frame points with their times, and each one's true place in the
// timestamp's frame.
struct Sweep {
  std::vector<PointXYZI> points;
  std::vector<float> times;
  std::vector<Eigen::Vector3d> truth;
};
Sweep courtyardSweep() {
  Sweep s;
  const int cols = 900;
  for (int c = 0; c < cols; ++c) {
    const double az = M_PI - 2 * M_PI * (c + 0.5) / cols;
    const double t = -az / (2 * M_PI) * 0.1;
    const Eigen::Isometry3d T = arcPose(t);
    for (const double el : {-0.15, -0.05, 0.05}) {
      const Eigen::Vector3d dl(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                               std::sin(el));
      const Eigen::Vector3d o = T.translation(), d = T.linear() * dl;
      // |o + r d|_xy = 25: the far root.
      const double a = d.head<2>().squaredNorm(), b = 2 * o.head<2>().dot(d.head<2>()),
                   cc = o.head<2>().squaredNorm() - 625.0;
      const double r = (-b + std::sqrt(b * b - 4 * a * cc)) / (2 * a);
      const Eigen::Vector3d p = dl * r;
      s.points.push_back({float(p.x()), float(p.y()), float(p.z()), 0.5f});
      s.times.push_back(float(t));
      s.truth.push_back(T * p);  // the timestamp's frame is the world's here (arcPose(0) = I)
    }
  }
  return s;
}

double maxError(const std::vector<PointXYZI>& pts, const std::vector<Eigen::Vector3d>& truth) {
  double e = 0;
  for (std::size_t i = 0; i < pts.size(); ++i)
    e = std::max(e, (pts[i].xyz().cast<double>() - truth[i]).norm());
  return e;
}

// With the motion measured from the previous scan's pose (0.1 s before) to this one, every point
// returns to its place within 3 cm (on this hard turn, 7 m/s^2 sideways, the chord of the last
// 0.1 s is 1.4 degrees off the heading, and the arc bends 1 cm from it in 0.05 s); not
// de-skewed, the rear is 0.7 m off.
TEST(Deskew, ASweepOnACurveReturnsToItsPlace) {
  Sweep s = courtyardSweep();
  const double before = maxError(s.points, s.truth);
  EXPECT_GT(before, 0.6);
  const SweepMotion m = SweepMotion::between(arcPose(-0.1), -0.1, arcPose(0.0), 0.0);
  EXPECT_NEAR(m.omega.z(), 0.5, 1e-9);
  EXPECT_NEAR(m.v.norm(), 14.0, 0.02);
  const double shift = deskewPoints(s.points, s.times, m);
  EXPECT_NEAR(shift, before, 0.02);
  EXPECT_LT(maxError(s.points, s.truth), 0.03);
}

// The azimuth's time: the rear at -sweep / 2, the left at -sweep / 4, the front at 0, the right
// at +sweep / 4 (clockwise seen from above).
TEST(Deskew, AzimuthTimesRunClockwiseFromTheRear) {
  const std::vector<PointXYZI> p = {
      {-10, 1e-3f, 0, 0}, {0, 10, 0, 0}, {10, 0, 0, 0}, {0, -10, 0, 0}, {-10, -1e-3f, 0, 0}};
  const auto t = azimuthTimes(p, 0.1);
  ASSERT_EQ(t.size(), 5u);
  EXPECT_NEAR(t[0], -0.05, 1e-5);
  EXPECT_NEAR(t[1], -0.025, 1e-6);
  EXPECT_NEAR(t[2], 0.0, 1e-7);
  EXPECT_NEAR(t[3], 0.025, 1e-6);
  EXPECT_NEAR(t[4], 0.05, 1e-5);
}

// No motion (a gap, or the poses' times out of order) moves nothing; times that do not match the
// points are refused.
TEST(Deskew, NoMotionMovesNothingAndMismatchedTimesAreRefused) {
  Sweep s = courtyardSweep();
  const auto copy = s.points;
  const SweepMotion none = SweepMotion::between(arcPose(0.0), 0.0, arcPose(0.1), 0.0);  // dt 0
  EXPECT_EQ(deskewPoints(s.points, s.times, none), 0.0);
  for (std::size_t i = 0; i < copy.size(); ++i) ASSERT_EQ(s.points[i].x, copy[i].x);
  s.times.pop_back();
  EXPECT_THROW(deskewPoints(s.points, s.times, SweepMotion{}), std::invalid_argument);
}

// The scan period behind the azimuth times: the median interval, a dropped scan or a repeated
// stamp left out.
TEST(Deskew, ScanPeriodIsTheMedianInterval) {
  EXPECT_NEAR(scanPeriod({0.0, 0.05, 0.10, 0.20, 0.20, 0.25}), 0.05, 1e-12);
  EXPECT_EQ(scanPeriod({3.0}), 0.0);
  EXPECT_EQ(scanPeriod({0.0, 2.0, 4.0}), 0.0);  // gaps over 1 s
}

}  // namespace
}  // namespace cleanmap
