// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.0 (our addition): undoing the sensor's motion during a sweep. A spinning lidar takes
// 0.1 s (at 10 Hz) to turn once; a car at 14 m/s moves 1.4 m meanwhile, so a scan's points lie in
// as many sensor frames as it has firings. Each point is moved into the frame of the scan's
// timestamp (the frame of its pose) under constant velocity.
#pragma once
#include <Eigen/Geometry>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap {

/// A constant-velocity motion in the sensor's own frame: rotation vector and translation per
/// second. The pose at time t after the reference is rotated by exp(t omega) and translated by
/// t v (the rotation at a constant rate, the translation linear: exact at the poses it joins).
struct SweepMotion {
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();  ///< rad/s
  Eigen::Vector3d v = Eigen::Vector3d::Zero();      ///< m/s
  /// The motion that takes pose `a` (time ta) to pose `b` (tb > ta), both sensor-to-world.
  static SweepMotion between(const Eigen::Isometry3d& a, double ta, const Eigen::Isometry3d& b,
                             double tb);
};

/// Per-point times (s, relative to the scan's timestamp) of a sweep that runs clockwise from the
/// rear (azimuth +pi) through the front (time 0, the timestamp) to the rear again in `sweep_s`,
/// as KITTI's HDL-64E and the simulator's lidar: t = -azimuth / (2 pi) * sweep_s.
std::vector<float> azimuthTimes(const std::vector<PointXYZI>& points, double sweep_s);

/// Moves each point, seen at times[i] (s after the scan's timestamp; before it if negative), into
/// the sensor frame at the timestamp: p' = exp(t [omega]x) p + t v. times.size() == points.size().
/// Returns the largest distance a point moved (m).
double deskewPoints(std::vector<PointXYZI>& points, const std::vector<float>& times,
                    const SweepMotion& motion);

}  // namespace cleanmap
