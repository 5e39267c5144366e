// SPDX-License-Identifier: BSD-3-Clause
// Core data types (DESIGN §1): scans, per-point labels, pinhole cameras. Eigen only: no MRPT,
// no OpenCV (images and frames are in frame.h).
#pragma once
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace cleanmap {

/// One lidar return in the sensor frame; same memory layout as a KITTI `.bin` record.
struct PointXYZI {
  float x = 0, y = 0, z = 0, intensity = 0;
  Eigen::Vector3f xyz() const { return {x, y, z}; }
};
static_assert(sizeof(PointXYZI) == 16, "PointXYZI must match the KITTI .bin record");

/// One sweep. Points are finite; invalid input points were dropped and are remembered through
/// `original_index` so per-point outputs can be written in the original order (DESIGN §4).
struct Scan {
  std::vector<PointXYZI> points;  ///< sensor frame, metres
  double timestamp = 0.0;         ///< seconds (epoch or sequence-relative, as the input gives)
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< sensor pose in the world
  bool has_pose = false;
  /// original_index[i] = index of points[i] in the input; empty means the identity.
  std::vector<uint32_t> original_index;
  std::size_t original_size = 0;    ///< number of points in the input, invalid ones included
  std::size_t dropped_invalid = 0;  ///< NaN / infinite points removed on reading
  /// DESIGN §2.0: each point's time in seconds after `timestamp`, where the input gives it (a
  /// Velodyne's packets, a rotating scan's columns); empty where it does not. Kept beside
  /// `points` (same order) until the points are de-skewed.
  std::vector<float> point_time;

  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  uint32_t originalIndex(std::size_t i) const {
    return original_index.empty() ? static_cast<uint32_t>(i) : original_index[i];
  }
};

/// Per-point labels, SemanticKITTI-MOS convention (DESIGN §4); the lower 16 bits are the class.
enum Label : uint32_t {
  kUnclassified = 0,  ///< out of range or invalid (ground-truth: ignore)
  kOutlier = 1,       ///< ground-truth only: ignore
  kStatic = 9,
  kGround = 40,
  kMoving = 251,
};
using Labels = std::vector<uint32_t>;

/// Ground-truth semantics of a SemanticKITTI id (DESIGN §5).
enum class GtClass { kIgnore, kStatic, kMoving };
inline GtClass gtClass(uint32_t label) {
  const uint32_t id = label & 0xFFFFu;
  if (id == 0 || id == 1) return GtClass::kIgnore;
  if (id >= 251 && id <= 259) return GtClass::kMoving;
  return GtClass::kStatic;
}

/// Rectified pinhole camera: pixel ~ P * T_cam_lidar * [x y z 1]^T (KITTI convention, where P is a
/// rectified projection such as P2 and T_cam_lidar maps lidar to the rectified reference camera).
struct PinholeCamera {
  Eigen::Matrix<double, 3, 4> P = Eigen::Matrix<double, 3, 4>::Zero();
  Eigen::Isometry3d T_cam_lidar = Eigen::Isometry3d::Identity();
  int width = 0, height = 0;
  std::string name;  ///< e.g. "image_2"

  /// Full 3x4 lidar-to-pixel matrix.
  Eigen::Matrix<double, 3, 4> lidarToPixel() const { return P * T_cam_lidar.matrix(); }
  double focal() const { return P(0, 0); }
  /// Intrinsics K (left 3x3 of P) and the pose of this camera's own optical frame relative to the
  /// lidar (P = K [I | K^-1 p4] in the rectified frame).
  Eigen::Matrix3d K() const { return P.leftCols<3>(); }
  Eigen::Isometry3d opticalFromLidar() const;
  /// Projects a lidar-frame point; nullopt when behind the camera or outside the image.
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_lidar) const;
};

/// Drops NaN/inf points in place, filling original_index / dropped_invalid. Returns the count.
std::size_t dropInvalidPoints(Scan& scan);

}  // namespace cleanmap
