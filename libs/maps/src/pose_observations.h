// SPDX-License-Identifier: BSD-3-Clause
// insertOpts `use_pose_observations` (DESIGN §4b): a map fed every observation of a rawlog, as
// RawLogViewer's "Map from odometry" does, takes each scan's pose from the rawlog's own
// CObservationRobotPose (3D, same timestamp) instead of the 2D odometry pose it is handed.
#pragma once
#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/poses/CPose3D.h>

#include <cmath>
#include <optional>
#include <string>
#include <utility>

#include "cleanmap/core/error.h"
#include "cleanmap/core/types.h"
#include "cleanmap/mrpt/convert.h"

namespace cleanmap_maps {

using LoggedPose = std::optional<std::pair<double, mrpt::poses::CPose3D>>;

/// Remembers `obs` in `last` if it is a CObservationRobotPose; true then.
inline bool takePoseObservation(const mrpt::obs::CObservation& obs, LoggedPose& last) {
  const auto* rp = dynamic_cast<const mrpt::obs::CObservationRobotPose*>(&obs);
  if (!rp) return false;
  last = std::make_pair(mrpt::Clock::toDouble(rp->timestamp), rp->pose.mean);
  return true;
}

/// The robot pose logged within 10 ms of the scan `obs`. Throws cleanmap::Error naming the scan.
inline mrpt::poses::CPose3D loggedPoseOf(const mrpt::obs::CObservation& obs,
                                         const LoggedPose& last) {
  const double t = mrpt::Clock::toDouble(obs.timestamp);
  if (!last || std::abs(last->first - t) > 0.01)
    throw cleanmap::Error(
        std::string(obs.GetRuntimeClass()->className) + " '" + obs.sensorLabel + "'",
        "use_pose_observations: no CObservationRobotPose within 10 ms before it");
  return last->second;
}

/// What a map inserts from `obs`: its lidar scan (sensor frame, timestamped) posed at
/// robot pose (+) sensor pose, composed here because 2.5.8's point-cloud insertion drops the robot
/// pose (MRPT_NOTES); no robot pose means the origin, as in MRPT. With `use_logged` the robot pose
/// is the rawlog's own (see above) and a CObservationRobotPose is remembered: `consumed`.
struct PosedObservation {
  bool consumed = false;               ///< a pose observation, taken
  std::optional<cleanmap::Scan> scan;  ///< empty: not a lidar observation
};

inline PosedObservation posedScanOf(const mrpt::obs::CObservation& obs,
                                    const std::optional<const mrpt::poses::CPose3D>& robotPose,
                                    bool use_logged, LoggedPose& logged) {
  PosedObservation out;
  if (use_logged && takePoseObservation(obs, logged)) {
    out.consumed = true;
    return out;
  }
  out.scan = cleanmap::mrpt::scanFromObservation(obs);
  if (!out.scan) return out;
  mrpt::poses::CPose3D sensor;
  obs.getSensorPose(sensor);
  std::optional<const mrpt::poses::CPose3D> robot = robotPose;
  if (use_logged) robot.emplace(loggedPoseOf(obs, logged));
  out.scan->pose = cleanmap::mrpt::toIsometry(robot ? *robot + sensor : sensor);
  out.scan->has_pose = true;
  return out;
}

}  // namespace cleanmap_maps
