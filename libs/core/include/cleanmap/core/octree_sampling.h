// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2c / paper §II-C (end): octree leaf sampling with OctoMap keys.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <vector>

#include "cleanmap/core/params.h"

namespace cleanmap {

struct Leaf {
  std::vector<uint32_t> members;  ///< indices into the candidate list
  std::vector<uint32_t> tested;   ///< the subset to test (all if fewer than tau_np members)
};

/// Groups candidates (world frame) by their OctoMap key at `leaf` resolution, in a deterministic
/// order, and draws each dense leaf's ceil(n * fraction) tested points with `rng`.
std::vector<Leaf> planLeaves(const std::vector<Eigen::Vector3d>& candidates, const OctreeParams& p,
                             std::mt19937_64& rng);

/// A leaf is moving iff at least half of its tested points are moving.
inline bool leafIsMoving(std::size_t tested_moving, std::size_t tested) {
  return tested > 0 && 2 * tested_moving >= tested;
}

}  // namespace cleanmap
