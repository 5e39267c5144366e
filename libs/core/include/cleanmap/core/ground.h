// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2a / paper §II-B: ground removal by height propagation on a 2D grid.
#pragma once
#include <cstdint>
#include <vector>

#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

/// Ground flags (1 = ground) for `points` (sensor frame, z up). Only points with
/// |x|, |y| <= half_extent are considered (others get 0); half_extent is rounded up to cells.
/// Cells are visited ring by ring from the sensor's cell; a cell is ground iff
/// H - h < s and H < hat_h + s (Eq. 1), where hat_h is the largest propagated height of its
/// inner-ring neighbours; it propagates H if ground, else hat_h; empty cells propagate hat_h.
std::vector<uint8_t> segmentGround(const std::vector<PointXYZI>& points, const GroundParams& p,
                                   double half_extent);

}  // namespace cleanmap
