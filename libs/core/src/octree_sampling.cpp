// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/octree_sampling.h"

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>

namespace cleanmap {

void planLeaves(const std::vector<Eigen::Vector3d>& candidates, const OctreeParams& p,
                std::mt19937_64& rng, LeafPlan& plan) {
  // An empty OcTree is only used for its key arithmetic (coordToKeyChecked at the leaf
  // resolution).
  const octomap::OcTree tree(p.leaf);
  const auto n_cand = static_cast<uint32_t>(candidates.size());
  // Each candidate's leaf, leaves numbered in the order of their first candidate.
  plan.ids_.clear();
  plan.ids_.reserve(candidates.size());
  plan.leaf_of_.resize(candidates.size());
  uint32_t n_leaves = 0;
  for (uint32_t i = 0; i < n_cand; ++i) {
    const auto& c = candidates[i];
    octomap::OcTreeKey key;
    uint32_t id = n_leaves;  // outside OctoMap's range: its own leaf
    if (tree.coordToKeyChecked(
            octomap::point3d(static_cast<float>(c.x()), static_cast<float>(c.y()),
                             static_cast<float>(c.z())),
            key)) {
      bool added = false;
      uint32_t& slot =
          plan.ids_.get(uint64_t(key[0]) | uint64_t(key[1]) << 16 | uint64_t(key[2]) << 32, &added);
      if (added) slot = n_leaves;
      id = slot;
    }
    if (id == n_leaves) ++n_leaves;
    plan.leaf_of_[i] = id;
  }
  // Members grouped by leaf, in candidate order within each; the dense leaves' draws from copies.
  const std::size_t tau = static_cast<std::size_t>(std::max(p.tau_np, 1));
  plan.members_.assign(plan.leaf_of_, n_leaves);
  plan.leaves_.resize(n_leaves);
  std::size_t dense = 0;
  for (std::size_t l = 0; l < n_leaves; ++l) {
    plan.leaves_[l].members = plan.members_[l];
    if (plan.members_[l].size() >= tau) dense += plan.members_[l].size();
  }
  plan.drawn_.resize(dense);
  plan.tested_total_ = 0;
  uint32_t* drawn = plan.drawn_.data();
  for (Leaf& leaf : plan.leaves_) {  // in leaf order, so the draw sequence is deterministic
    const std::size_t n = leaf.members.size();
    if (n < tau) {
      leaf.tested = leaf.members;
    } else {
      const auto k = static_cast<std::size_t>(std::ceil(static_cast<double>(n) * p.fraction));
      std::copy(leaf.members.begin(), leaf.members.end(), drawn);
      // Partial Fisher-Yates: the first k entries become a uniform random subset.
      for (std::size_t j = 0; j < k; ++j) {
        std::uniform_int_distribution<std::size_t> pick(j, n - 1);
        std::swap(drawn[j], drawn[pick(rng)]);
      }
      leaf.tested = IndexRange{drawn, k};
      drawn += n;
    }
    plan.tested_total_ += leaf.tested.size();
  }
}

}  // namespace cleanmap
