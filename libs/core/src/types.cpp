// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/types.h"

#include <cmath>

namespace cleanmap {

Eigen::Isometry3d PinholeCamera::opticalFromLidar() const {
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = K().inverse() * P.col(3);
  return shift * T_cam_lidar;
}

std::optional<Eigen::Vector2d> PinholeCamera::project(const Eigen::Vector3d& p_lidar) const {
  const Eigen::Vector3d uvw = lidarToPixel() * p_lidar.homogeneous();
  if (uvw.z() <= 1e-6) return std::nullopt;
  const Eigen::Vector2d px = uvw.head<2>() / uvw.z();
  if (px.x() < 0 || px.y() < 0 || px.x() >= width || px.y() >= height) return std::nullopt;
  return px;
}

std::size_t dropInvalidPoints(Scan& scan) {
  auto finite = [](const PointXYZI& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) &&
           std::isfinite(p.intensity);
  };
  if (scan.original_size == 0) scan.original_size = scan.points.size();
  std::size_t bad = 0;
  for (const auto& p : scan.points) bad += finite(p) ? 0 : 1;
  if (bad == 0) return 0;
  std::vector<PointXYZI> kept;
  std::vector<uint32_t> index;
  std::vector<float> times;
  const bool timed = scan.point_time.size() == scan.points.size();
  kept.reserve(scan.points.size() - bad);
  index.reserve(scan.points.size() - bad);
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    if (!finite(scan.points[i])) continue;
    kept.push_back(scan.points[i]);
    index.push_back(scan.originalIndex(i));
    if (timed) times.push_back(scan.point_time[i]);
  }
  scan.points = std::move(kept);
  scan.original_index = std::move(index);
  if (timed) scan.point_time = std::move(times);
  scan.dropped_invalid += bad;
  return bad;
}

}  // namespace cleanmap
