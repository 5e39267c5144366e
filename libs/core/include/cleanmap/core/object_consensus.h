// SPDX-License-Identifier: BSD-3-Clause
// Object consensus (our addition, doc/OBJECTS.md): the per-point test of DESIGN §2b sees only the
// parts of a vehicle whose space becomes empty in other scans; a long vehicle moving along its
// own length keeps its sides occupied. A rigid object moves as a whole: if enough of a connected,
// vehicle-sized group of non-ground points is moving, all of it is.
#pragma once
#include <cstdint>
#include <vector>

#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"

namespace cleanmap {

struct ObjectConsensusStats {
  std::size_t objects = 0;           ///< connected groups of non-ground points
  std::size_t moving_objects = 0;    ///< groups turned moving as a whole
  std::size_t points_added = 0;      ///< points turned moving by the consensus
  std::size_t points_removed = 0;    ///< moving points turned static (a few in a static object)
  std::size_t persisted = 0;         ///< of moving_objects, those kept moving by the hysteresis
  std::size_t body_points_kept = 0;  ///< moving points of a body a static component kept
  std::size_t foot_points_left = 0;  ///< points at a moving component's foot not turned moving
  /// Points of a moving component's raised parts (joined to it only below the foot) with no
  /// moving point of their own, not turned moving.
  std::size_t still_part_points_left = 0;
};

/// Groups `points[i]` with `member[i]` (in crop, not ground) into 26-connected voxel components
/// and sets `moving[i]` = 1 for every point of a component that passes the rule of `p`.
/// `near_previous[i]` (optional): point i lies within p.persist_radius of a moving point of the
/// previous scan (world frame); it lets a partly moving object stay moving (hysteresis).
/// Deterministic; O(points).
ObjectConsensusStats objectConsensus(const std::vector<PointXYZI>& points,
                                     const std::vector<uint8_t>& member,
                                     std::vector<uint8_t>& moving, const ObjectParams& p,
                                     const std::vector<uint8_t>* near_previous = nullptr);

}  // namespace cleanmap
