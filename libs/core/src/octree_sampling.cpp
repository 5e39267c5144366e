// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/octree_sampling.h"

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace cleanmap {

std::vector<Leaf> planLeaves(const std::vector<Eigen::Vector3d>& candidates, const OctreeParams& p,
                             std::mt19937_64& rng) {
  // An empty OcTree is only used for its key arithmetic (coordToKey at the leaf resolution).
  const octomap::OcTree tree(p.leaf);
  std::unordered_map<octomap::OcTreeKey, uint32_t, octomap::OcTreeKey::KeyHash> leaf_of;
  std::vector<Leaf> leaves;
  for (uint32_t i = 0; i < candidates.size(); ++i) {
    const auto& c = candidates[i];
    octomap::OcTreeKey key;
    if (!tree.coordToKeyChecked(
            octomap::point3d(static_cast<float>(c.x()), static_cast<float>(c.y()),
                             static_cast<float>(c.z())),
            key)) {
      leaves.push_back(Leaf{{i}, {}});  // outside OctoMap's range: its own leaf
      continue;
    }
    const auto [it, added] = leaf_of.emplace(key, static_cast<uint32_t>(leaves.size()));
    if (added) leaves.emplace_back();
    leaves[it->second].members.push_back(i);
  }
  // Leaves are in order of first appearance, so the draw sequence is deterministic.
  const std::size_t tau = static_cast<std::size_t>(std::max(p.tau_np, 1));
  for (auto& leaf : leaves) {
    const std::size_t n = leaf.members.size();
    if (n < tau) {
      leaf.tested = leaf.members;
      continue;
    }
    const auto k = static_cast<std::size_t>(std::ceil(static_cast<double>(n) * p.fraction));
    leaf.tested = leaf.members;
    // Partial Fisher-Yates: the first k entries become a uniform random subset.
    for (std::size_t j = 0; j < k; ++j) {
      std::uniform_int_distribution<std::size_t> pick(j, n - 1);
      std::swap(leaf.tested[j], leaf.tested[pick(rng)]);
    }
    leaf.tested.resize(k);
  }
  return leaves;
}

}  // namespace cleanmap
