// SPDX-License-Identifier: BSD-3-Clause
// Indices grouped by a dense group id in two flat arrays (a counting sort), for the per-scan
// groupings of the pipeline (octree leaves, the camera check's cells): no vector per group, and
// the arrays' memory is kept when an instance is filled again (issue #16).
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cleanmap {

/// Indices held by an array that outlives the range (a Grouped's, a LeafPlan's).
struct IndexRange {
  const uint32_t* first = nullptr;
  std::size_t n = 0;
  const uint32_t* begin() const { return first; }
  const uint32_t* end() const { return first + n; }
  std::size_t size() const { return n; }
  bool empty() const { return n == 0; }
  uint32_t operator[](std::size_t i) const { return first[i]; }
  uint32_t front() const { return first[0]; }
};

class Grouped {
 public:
  /// Groups item k, of value `value[k]` (k itself without `value`), into group `group[k]`
  /// (< groups); within a group the items keep their order.
  void assign(const std::vector<uint32_t>& group, std::size_t groups,
              const std::vector<uint32_t>* value = nullptr) {
    start_.assign(groups + 1, 0);
    for (const uint32_t g : group) ++start_[g + 1];
    for (std::size_t g = 0; g < groups; ++g) start_[g + 1] += start_[g];
    next_.assign(start_.begin(), start_.end() - 1);
    items_.resize(group.size());
    for (std::size_t k = 0; k < group.size(); ++k)
      items_[next_[group[k]]++] = value ? (*value)[k] : static_cast<uint32_t>(k);
  }
  std::size_t size() const { return start_.empty() ? 0 : start_.size() - 1; }
  IndexRange operator[](std::size_t g) const {
    return IndexRange{items_.data() + start_[g], start_[g + 1] - start_[g]};
  }

 private:
  std::vector<uint32_t> start_, next_, items_;
};

}  // namespace cleanmap
