// SPDX-License-Identifier: BSD-3-Clause
// Ground-truth object tracks (`objects.json` of ../shared/data, format in doc/FORMATS.md).
#pragma once
#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

namespace cleanmap::io {

enum class Motion { kStatic, kMoving, kUncertain };

/// One object in one scan; centre and yaw in that scan's lidar frame.
struct ObjectState {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  ///< l (along yaw), w, h in metres
  double yaw = 0.0;
  Motion motion = Motion::kStatic;
  int n_points = 0;
  /// True if lidar-frame point p lies inside the box inflated by `margin` metres.
  bool contains(const Eigen::Vector3d& p, double margin = 0.0) const;
};

struct GtObject {
  int id = 0;
  std::string name, cls;
  std::map<std::size_t, ObjectState> frames;  ///< by scan index
  bool movingAnywhere() const;
};

/// Reads objects.json. Throws cleanmap::Error naming the file and the offending field.
std::vector<GtObject> readObjects(const std::string& path);

}  // namespace cleanmap::io
