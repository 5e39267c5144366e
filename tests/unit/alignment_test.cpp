// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §3 "Camera poses": vision::alignView on a rendered scene with known poses: a textured
// road 1.6 m below the camera and a textured wall 14 m ahead, seen from two cameras 0.6 m apart.
// The second camera's pose is given with an error; the alignment on the first scan's points must
// find the true one, and leave an exact pose or an untextured scene alone.
#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/core.hpp>

#include "cleanmap/vision/alignment.h"
#include "cleanmap/vision/image_validation.h"

using namespace cleanmap;

namespace {

constexpr int kW = 640, kH = 360;
constexpr double kF = 500, kGround = 1.6, kWall = 14.0;

// Lidar frame = camera optical frame (x right, y down, z forward); the world is the first
// camera's frame.
PinholeCamera camera() {
  PinholeCamera c;
  c.width = kW;
  c.height = kH;
  c.P << kF, 0, kW / 2.0, 0, 0, kF, kH / 2.0, 0, 0, 0, 1, 0;
  c.name = "test";
  return c;
}

// A smooth texture (features of 0.2-1 m) of the plane coordinates (a, b); flat: one grey.
double texture(double a, double b, bool flat) {
  if (flat) return 0.5;
  return 0.5 + 0.18 * std::sin(6.1 * a) * std::cos(4.3 * b) + 0.12 * std::sin(13.7 * a + 9.1 * b) +
         0.08 * std::cos(21.0 * b - 5.0 * a);
}

// Where the ray from `o` along `d` (world) meets the road (y = kGround) or the wall (z = kWall),
// the nearer; false when neither is in front.
bool hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, Eigen::Vector3d& x) {
  double t = std::numeric_limits<double>::infinity();
  if (d.y() > 1e-9) t = (kGround - o.y()) / d.y();
  if (d.z() > 1e-9) t = std::min(t, (kWall - o.z()) / d.z());
  if (!std::isfinite(t) || t <= 0) return false;
  x = o + t * d;
  return true;
}
double shade(const Eigen::Vector3d& x, bool flat) {
  return std::abs(x.y() - kGround) < 1e-6 ? texture(x.x(), x.z(), flat)
                                          : texture(x.x(), x.y(), flat);
}

// The image and the lidar points (sensor frame, every 3rd pixel's ray) of a camera at `pose`.
struct Shot {
  cv::Mat image;
  std::vector<PointXYZI> points;
};
Shot shoot(const Eigen::Isometry3d& pose, bool flat) {
  Shot s;
  s.image.create(kH, kW, CV_8UC3);
  for (int v = 0; v < kH; ++v)
    for (int u = 0; u < kW; ++u) {
      const Eigen::Vector3d dl((u - kW / 2.0) / kF, (v - kH / 2.0) / kF, 1);
      Eigen::Vector3d x;
      const double g = hit(pose.translation(), pose.linear() * dl.normalized(), x)
                           ? std::clamp(shade(x, flat), 0.0, 1.0)
                           : 0.8;
      const auto c = static_cast<uchar>(std::lround(255 * g));
      s.image.at<cv::Vec3b>(v, u) = {c, c, c};
      Eigen::Vector3d xw;
      if (u % 3 == 0 && v % 3 == 0 &&
          hit(pose.translation(), pose.linear() * dl.normalized(), xw)) {
        const Eigen::Vector3d q = pose.inverse() * xw;  // the return, in the sensor frame
        s.points.push_back({float(q.x()), float(q.y()), float(q.z()), 0.f});
      }
    }
  return s;
}

Eigen::Isometry3d pose(double x, double y, double z, double yaw_deg = 0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// The first scan's points in the world (its pose is the identity).
std::vector<Eigen::Vector3d> world(const Shot& s) {
  std::vector<Eigen::Vector3d> w;
  for (const auto& p : s.points) w.push_back(p.xyz().cast<double>());
  return w;
}

}  // namespace

TEST(Alignment, FindsTheTruePoseOfACameraGivenWithAnError) {
  const Eigen::Isometry3d first = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d second = pose(0.05, 0, 0.6, 0.3);  // truly there
  const Shot a = shoot(first, false), b = shoot(second, false);
  // Given 6 cm off sideways, 4 cm off forward, 0.2 degrees off in yaw.
  const Eigen::Isometry3d given = second * pose(0.06, 0, -0.04, 0.2);
  const auto va = vision::makeCameraView(a.image, a.points, first, camera(), 0, "a", 4);
  const auto vb = vision::makeCameraView(b.image, b.points, given, camera(), 1, "b", 4);
  const auto al = vision::alignView(va, vb, world(a), vision::AlignParams{});
  ASSERT_TRUE(al.has_value());
  const auto fixed = vision::corrected(vb, al->correction);
  const auto truth = vision::makeCameraView(b.image, b.points, second, camera(), 1, "b", 4);
  const Eigen::Isometry3d err = fixed.optical_from_world * truth.optical_from_world.inverse();
  EXPECT_LT(err.translation().norm(), 0.01) << err.translation().transpose();
  EXPECT_LT(Eigen::AngleAxisd(err.linear()).angle() * 180 / M_PI, 0.05);
  EXPECT_LT(al->error_after, 0.5 * al->error_before);
  EXPECT_GT(al->points, 100);
}

TEST(Alignment, LeavesAnExactPoseAndAnUntexturedSceneAlone) {
  const Eigen::Isometry3d first = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d second = pose(0.05, 0, 0.6, 0.3);
  {  // exact: nothing to gain, no correction
    const Shot a = shoot(first, false), b = shoot(second, false);
    const auto va = vision::makeCameraView(a.image, a.points, first, camera(), 0, "a", 4);
    const auto vb = vision::makeCameraView(b.image, b.points, second, camera(), 1, "b", 4);
    EXPECT_FALSE(vision::alignView(va, vb, world(a), vision::AlignParams{}).has_value());
  }
  {  // flat grey road and wall: no textured point to align on
    const Shot a = shoot(first, true), b = shoot(second, true);
    const auto va = vision::makeCameraView(a.image, a.points, first, camera(), 0, "a", 4);
    const auto vb = vision::makeCameraView(b.image, b.points, second * pose(0.06, 0, -0.04),
                                           camera(), 1, "b", 4);
    EXPECT_FALSE(vision::alignView(va, vb, world(a), vision::AlignParams{}).has_value());
  }
  {  // an error beyond max_translation is refused, not half corrected
    const Shot a = shoot(first, false), b = shoot(second, false);
    const auto va = vision::makeCameraView(a.image, a.points, first, camera(), 0, "a", 4);
    const auto vb = vision::makeCameraView(b.image, b.points, second * pose(0.06, 0, -0.04),
                                           camera(), 1, "b", 4);
    vision::AlignParams tight;
    tight.max_translation = 0.03;
    EXPECT_FALSE(vision::alignView(va, vb, world(a), tight).has_value());
  }
}

// A correction beyond `small_translation` must lower the error by `large_gain`, not `min_gain`:
// a true misalignment that large leaves most of the error (here the render is exact, so nearly
// all of it), while a wrong minimum explains only the images' noise. The simulated drift of 10 %
// of the path has steps of 0.15-0.25 m between two scans (DESIGN §3 "Camera poses").
TEST(Alignment, CorrectsALargeErrorWhereTheErrorFallsAsMuchAsItShould) {
  const Eigen::Isometry3d first = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d second = pose(0.05, 0, 0.6, 0.3);
  const Shot a = shoot(first, false), b = shoot(second, false);
  const auto va = vision::makeCameraView(a.image, a.points, first, camera(), 0, "a", 4);
  const auto truth = vision::makeCameraView(b.image, b.points, second, camera(), 1, "b", 4);
  // Given 20 cm off sideways and 12 cm off forward: beyond small_translation (0.15 m).
  const auto vb =
      vision::makeCameraView(b.image, b.points, second * pose(0.2, 0, -0.12), camera(), 1, "b", 4);
  const vision::AlignParams p;
  const auto al = vision::alignView(va, vb, world(a), p);
  ASSERT_TRUE(al.has_value());
  EXPECT_GT(al->correction.translation().norm(), p.small_translation);
  const Eigen::Isometry3d err =
      vision::corrected(vb, al->correction).optical_from_world * truth.optical_from_world.inverse();
  EXPECT_LT(err.translation().norm(), 0.01) << err.translation().transpose();
  const double gain = 1 - al->error_after / al->error_before;
  EXPECT_GT(gain, p.large_gain);
  {  // the same alignment, asked for more than it gained: refused
    vision::AlignParams strict = p;
    strict.large_gain = 0.5 * (gain + 1);
    EXPECT_FALSE(vision::alignView(va, vb, world(a), strict).has_value());
    // ... while a small error still needs only min_gain
    const auto vs = vision::makeCameraView(b.image, b.points, second * pose(0.06, 0, -0.04),
                                           camera(), 1, "b", 4);
    EXPECT_TRUE(vision::alignView(va, vs, world(a), strict).has_value());
  }
  {  // small_translation = max_translation: every larger correction refused (the former rule)
    vision::AlignParams capped = p;
    capped.max_translation = capped.small_translation;
    EXPECT_FALSE(vision::alignView(va, vb, world(a), capped).has_value());
  }
}
