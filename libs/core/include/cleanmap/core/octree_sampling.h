// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2c / paper §II-C (end): octree leaf sampling with OctoMap keys.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <vector>

#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/grouped.h"
#include "cleanmap/core/params.h"

namespace cleanmap {

struct Leaf {
  IndexRange members;  ///< indices into the candidate list, increasing
  IndexRange tested;   ///< the subset to test (all if fewer than tau_np members)
};

/// The candidates grouped by leaf (planLeaves). Its arrays are kept from one plan to the next,
/// so a pipeline planning every scan allocates nothing per leaf (issue #16: 37,000 allocations a
/// kitti_highway scan before). Not copyable: its leaves point into its own arrays.
class LeafPlan {
 public:
  LeafPlan() = default;
  LeafPlan(LeafPlan&&) = default;  // the arrays move with their elements in place
  LeafPlan& operator=(LeafPlan&&) = default;
  LeafPlan(const LeafPlan&) = delete;
  LeafPlan& operator=(const LeafPlan&) = delete;

  std::size_t size() const { return leaves_.size(); }
  bool empty() const { return leaves_.empty(); }
  const Leaf& operator[](std::size_t l) const { return leaves_[l]; }
  std::vector<Leaf>::const_iterator begin() const { return leaves_.begin(); }
  std::vector<Leaf>::const_iterator end() const { return leaves_.end(); }
  std::size_t testedTotal() const { return tested_total_; }  ///< tested points over all leaves
  void clear() { leaves_.clear(), tested_total_ = 0; }

 private:
  friend void planLeaves(const std::vector<Eigen::Vector3d>&, const OctreeParams&, std::mt19937_64&,
                         LeafPlan&);
  std::vector<Leaf> leaves_;
  Grouped members_;                // the candidates by leaf
  std::vector<uint32_t> drawn_;    // the dense leaves' members, shuffled; tested is a prefix
  std::vector<uint32_t> leaf_of_;  // per candidate, its leaf
  CellMap<uint32_t> ids_;          // OctoMap key -> leaf
  std::size_t tested_total_ = 0;
};

/// Groups candidates (world frame) by their OctoMap key at `leaf` resolution, in a deterministic
/// order (the order of each leaf's first candidate; a candidate outside OctoMap's range is a leaf
/// of its own), and draws each dense leaf's ceil(n * fraction) tested points with `rng`. `plan`
/// is overwritten, its memory reused.
void planLeaves(const std::vector<Eigen::Vector3d>& candidates, const OctreeParams& p,
                std::mt19937_64& rng, LeafPlan& plan);

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
