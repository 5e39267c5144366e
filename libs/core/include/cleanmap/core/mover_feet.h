// SPDX-License-Identifier: BSD-3-Clause
// doc/OBJECTS.md rule 6, a mover's feet: the returns of a moving object within `ground.step` of
// the road (a car's lowest face and tyres, a walker's shoes) are ground for DESIGN §2a's point
// refinement and would stay in every map. Those standing under the mover, raised above the road
// around them, go with it.
#pragma once
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "cleanmap/core/ground.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

struct MoverFeetParams {
  /// m; a foot's nearest return above lies within this horizontal distance: the surface it
  /// continues down to the road, with the range noise of a return and a bumper's slant.
  double radius = 0.15;
  /// m; the least rise over the road around it, the median of the scan's other ground returns
  /// in the 3 x 3 ground cells (`cell`) around the foot; three times their scatter (1.4826 MAD)
  /// where that is larger, so a rough or noisy road's own returns are not raised.
  double rise = 0.03;
  double cell = 0.4;  ///< m; the ground grid's cell (GroundParams::cell)
  /// rad; the lidar's angle between rings: that return must lie within two ring steps at the
  /// foot's range above it (at least 0.3 m), the next ring up on the same surface.
  double ring_gap = 0.4 * 3.14159265358979323846 / 180.0;
};

/// Indices of the feet among `points` (sensor frame): points refined to ground (`ground` ==
/// kGroundRefined) in the crop (`in_crop`) whose nearest return above (horizontally, within
/// `radius`, and two ring steps up at most, at least 0.3 m; non-ground, in the crop) is moving
/// (`moving`), and that lie more than `rise` over the road around them. A static surface
/// straight above one (a wall's foot behind a walker's legs) keeps it. `pose` (sensor to world,
/// z up) gives the heights and horizontal distances. Every other ground point (any flag) is the
/// road's sample. Ascending order.
std::vector<uint32_t> moverFeet(const std::vector<PointXYZI>& points, const Eigen::Isometry3d& pose,
                                const std::vector<uint8_t>& ground,
                                const std::vector<uint8_t>& moving,
                                const std::vector<uint8_t>& in_crop, const MoverFeetParams& p);

}  // namespace cleanmap
