// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.2, "Self returns": the recording vehicle's own body (a roof rack, a mirror, the
// roof's edge) returns at the same place in the sensor frame in every scan, so while the vehicle
// drives, the windowed test sees its world place empty in the other scans and flags it moving.
#pragma once
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "cleanmap/core/moving_test.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

/// The rule's constants (DESIGN §2.2).
struct SelfReturns {
  static constexpr double kTravel = 1.0;     ///< m: a window scan compared lies this far away
  static constexpr double kTolerance = 0.1;  ///< m: a return this near P's sensor-frame place
  static constexpr double kShare = 0.75;     ///< of the compared scans at least
  static constexpr int kMinScans = 2;        ///< compared scans at least
};

/// Marks (self[i] = 1) the flagged members of a scan (sensor frame; `member`: in the crop, not
/// ground) that are the recording vehicle: within `range` m of the sensor horizontally, in a
/// component of member voxels (side `voxel`, 26-connected) that lies wholly within that range,
/// and with a return within SelfReturns::kTolerance of the same sensor-frame place in at least
/// kShare of the window scans whose sensor lies kTravel or more from `sensor_at` (the scan's
/// sensor, world frame; at least kMinScans of them). A mover beside the sensor that keeps pace
/// (a truck's side in a queue) reaches beyond the range; a static surface is not flagged. Fewer
/// compared scans (the vehicle stands, or crawls): none. Returns how many were marked.
std::size_t findSelfReturns(const std::vector<PointXYZI>& points,
                            const std::vector<uint8_t>& member, const std::vector<uint8_t>& flagged,
                            const Eigen::Vector3d& sensor_at, const std::vector<WindowScan>& window,
                            double range, double voxel, std::vector<uint8_t>& self);

}  // namespace cleanmap
