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

}  // namespace cleanmap_maps
