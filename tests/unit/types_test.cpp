// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "cleanmap/core/types.h"

using namespace cleanmap;

TEST(Scan, DropInvalidKeepsOriginalOrder) {
  Scan s;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  s.points = {{1, 2, 3, 0.5f}, {nan, 0, 0, 0}, {4, 5, 6, 0.1f}, {0, inf, 0, 0}, {7, 8, 9, nan}};
  EXPECT_EQ(dropInvalidPoints(s), 3u);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s.original_size, 5u);
  EXPECT_EQ(s.dropped_invalid, 3u);
  EXPECT_EQ(s.originalIndex(0), 0u);
  EXPECT_EQ(s.originalIndex(1), 2u);
  EXPECT_FLOAT_EQ(s.points[1].z, 6.0f);
  // A second pass keeps the mapping to the input, not to the first pass.
  s.points[0].x = nan;
  EXPECT_EQ(dropInvalidPoints(s), 1u);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s.originalIndex(0), 2u);
  EXPECT_EQ(s.dropped_invalid, 4u);
}

TEST(Scan, AllValidLeavesIdentityMapping) {
  Scan s;
  s.points = {{1, 2, 3, 0}, {4, 5, 6, 0}};
  EXPECT_EQ(dropInvalidPoints(s), 0u);
  EXPECT_TRUE(s.original_index.empty());
  EXPECT_EQ(s.originalIndex(1), 1u);
}

TEST(Labels, SemanticKittiClasses) {
  EXPECT_EQ(gtClass(0), GtClass::kIgnore);
  EXPECT_EQ(gtClass(1), GtClass::kIgnore);
  EXPECT_EQ(gtClass(9), GtClass::kStatic);
  EXPECT_EQ(gtClass(40), GtClass::kStatic);
  EXPECT_EQ(gtClass(250), GtClass::kStatic);
  EXPECT_EQ(gtClass(251), GtClass::kMoving);
  EXPECT_EQ(gtClass(259), GtClass::kMoving);
  EXPECT_EQ(gtClass(260), GtClass::kStatic);
  // Instance ids live in the upper 16 bits and do not change the class.
  EXPECT_EQ(gtClass((7u << 16) | 252u), GtClass::kMoving);
  EXPECT_EQ(gtClass((7u << 16) | 0u), GtClass::kIgnore);
}

// KITTI-like camera: lidar x forward, camera z forward.
PinholeCamera kittiLikeCamera() {
  PinholeCamera c;
  c.width = 1242;
  c.height = 375;
  c.P << 721.5, 0, 609.6, 44.86, 0, 721.5, 172.9, 0.2164, 0, 0, 1, 0.0027;
  Eigen::Matrix3d R;
  R << 0, -1, 0, 0, 0, -1, 1, 0, 0;  // lidar (x fwd, y left, z up) -> camera (x right, y down, z fwd)
  c.T_cam_lidar.linear() = R;
  c.T_cam_lidar.translation() = Eigen::Vector3d(0, -0.08, -0.27);
  return c;
}

TEST(PinholeCamera, ProjectsAheadAndRejectsBehind) {
  const auto c = kittiLikeCamera();
  const auto ahead = c.project({20, 0, 0});
  ASSERT_TRUE(ahead.has_value());
  EXPECT_NEAR(ahead->x(), 609.6 + 44.86 / 20.0, 0.5);  // near the principal point
  EXPECT_FALSE(c.project({-20, 0, 0}).has_value());    // behind
  EXPECT_FALSE(c.project({2, 30, 0}).has_value());     // far to the left, outside the image
}

TEST(PinholeCamera, OpticalFrameReproducesProjection) {
  const auto c = kittiLikeCamera();
  const Eigen::Vector3d p(15, 2, -1);
  const Eigen::Vector3d q = c.opticalFromLidar() * p;
  const Eigen::Vector3d uvw_opt = c.K() * q;
  const Eigen::Vector3d uvw = c.lidarToPixel() * p.homogeneous();
  EXPECT_NEAR(uvw_opt.x() / uvw_opt.z(), uvw.x() / uvw.z(), 1e-6);
  EXPECT_NEAR(uvw_opt.y() / uvw_opt.z(), uvw.y() / uvw.z(), 1e-6);
}
