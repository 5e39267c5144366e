// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2a / paper §II-B: ground removal by height propagation on a 2D grid.
#pragma once
#include <cstdint>
#include <optional>
#include <vector>

#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

/// segmentGround's flags: not ground; a point of a ground cell; a point of a cell an object
/// stands in, refined to ground for lying within `step` of the propagated ground height
/// (GroundParams::point_refine). Every user but mover_feet.h reads them as a yes / no.
enum GroundFlag : uint8_t { kNotGround = 0, kGroundCell = 1, kGroundRefined = 2 };

/// Ground flags (GroundFlag; non-zero = ground) for `points` (sensor frame, z up). Only points with
/// |x|, |y| <= half_extent are considered (others get 0); half_extent is rounded up to cells.
/// Cells are visited ring by ring from the sensor's cell; a cell is ground iff
/// H - h < s and H < hat_h + s (Eq. 1), where hat_h is the largest propagated height of its
/// inner-ring neighbours; it propagates H if ground, else hat_h; empty cells propagate hat_h.
/// `ground_z` is h_G of the sensor's own cell: the ground height below the sensor origin
/// (negative; -1.73 for KITTI's HDL-64E).
std::vector<uint8_t> segmentGround(const std::vector<PointXYZI>& points, const GroundParams& p,
                                   double half_extent, double ground_z);

/// DESIGN §2a, our addition (issue #15): the ground height below the sensor measured from one scan
/// (sensor frame, z up, roughly level): in each of 36 azimuth sectors, the third-lowest return
/// between 2 and 25 m horizontally (the road beside the car; the third, so that a stray return
/// below the road does not count), then the median over the sectors (cars, walls and curbs fill
/// a few). nullopt when fewer than 9 sectors have three returns.
std::optional<double> estimateGroundHeight(const std::vector<PointXYZI>& points);

}  // namespace cleanmap
