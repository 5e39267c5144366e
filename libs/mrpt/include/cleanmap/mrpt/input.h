// SPDX-License-Identifier: BSD-3-Clause
// One entry point for every input cleanmap accepts: a KITTI folder or an MRPT rawlog.
#pragma once
#include <memory>
#include <string>

#include "cleanmap/core/frame.h"

namespace cleanmap::mrpt {

struct InputOptions {
  bool allow_empty_scans = false;
  bool load_images = true;
  bool point_times = true;  ///< KITTI raw drives: point times, for the de-skew (DESIGN §2.0)
  /// Rawlogs: the sensorLabel of the lidar / camera to read ("" = the first in the file). A KITTI
  /// folder has one of each: naming one there is an error.
  std::string lidar_label, camera_label;
};

/// A directory opens as a KITTI sequence (odometry or raw), a file as a rawlog.
/// Throws cleanmap::Error naming the path if it is neither.
std::unique_ptr<FrameSource> openInput(const std::string& path, const InputOptions& opts = {});

}  // namespace cleanmap::mrpt
