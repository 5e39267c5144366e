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

/// leafIsMoving over the leaf's tested points, calling `is_moving(c)` for them in order only
/// until the majority is settled (half of them moving, or more than half not): the others
/// cannot change the decision (issue #16).
template <class IsMoving>
bool decideLeaf(const Leaf& leaf, IsMoving&& is_moving) {
  const std::size_t n = leaf.tested.size();
  std::size_t k = 0, moving = 0;
  for (; k < n && 2 * moving < n && 2 * (moving + n - k) >= n; ++k)
    moving += is_moving(leaf.tested[k]) ? 1 : 0;
  return leafIsMoving(moving, n);  // settled: the same as with every point tested
}

}  // namespace cleanmap
