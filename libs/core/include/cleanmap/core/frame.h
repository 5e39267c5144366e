// SPDX-License-Identifier: BSD-3-Clause
// What every reader delivers (DESIGN §1): a frame = one scan, its optional camera image and where
// it came from; a FrameSource streams them. The only core header that pulls in OpenCV.
#pragma once
#include <optional>
#include <string>

#include <opencv2/core/mat.hpp>

#include "cleanmap/core/types.h"

namespace cleanmap {

/// A camera frame taken with scan k.
struct Image {
  cv::Mat bgr;  ///< 8-bit, 3 channels (OpenCV order)
  double timestamp = 0.0;
};

/// One element of a sequence as every reader delivers it.
struct Frame {
  std::size_t index = 0;
  std::string stem;  ///< "000123" (KITTI file stem or 6-digit rawlog index), names output files
  std::string
      source;  ///< where the scan came from, for messages: a .bin path or "x.rawlog entry 12"
  Scan scan;
  std::optional<Image> image;
  /// The sensor's pose in the frame of the robot's odometry, where the input has odometry (rawlog
  /// CActionRobotMovement2D/3D or CObservationOdometry): GICP's initial guess (DESIGN §2.1).
  std::optional<Eigen::Isometry3d> odometry;
  /// The sensor's mounting on the vehicle (a rawlog's sensorPose), where the input says: its roll
  /// and pitch level the scan for the ground stage (DESIGN §2a), so a tilted lidar is handled.
  /// Absent: the sensor is level (KITTI).
  std::optional<Eigen::Isometry3d> mount;
};

/// A forward-only stream of frames: lets the pipeline keep only its window in memory.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// Next frame, or nullopt at the end. Throws cleanmap::Error on bad input.
  virtual std::optional<Frame> next() = 0;
  /// Number of frames if known up front.
  virtual std::optional<std::size_t> sizeHint() const { return std::nullopt; }
  /// The camera, if the sequence has one.
  virtual std::optional<PinholeCamera> camera() const { return std::nullopt; }
};

}  // namespace cleanmap
