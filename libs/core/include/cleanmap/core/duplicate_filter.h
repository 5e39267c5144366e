// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.3: a candidate is a duplicate if a static-map point contributed by the last W processed
// scans lies within d_dup.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <vector>

#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/params.h"

namespace cleanmap {

class DuplicateFilter {
 public:
  explicit DuplicateFilter(const FilterParams& p);

  /// True if a point inserted by one of the scans [scan - W, scan) lies within d_dup of p.
  bool isDuplicate(const Eigen::Vector3f& p, long scan) const;
  /// Adds the static points that scan `scan` contributed to the map, and forgets scans older
  /// than the window. Scans are inserted in increasing order.
  void insert(const std::vector<Eigen::Vector3f>& points, long scan);
  std::size_t size() const { return count_; }

 private:
  struct Entry {
    Eigen::Vector3f p;
    int32_t scan;
  };
  using Key = uint64_t;
  void prune(long oldest);

  FilterParams p_;
  float inv_;  // cells of side 2 d_dup: a query ball touches at most 2 x 2 x 2 of them
  // Entries of a cell are in insertion (= scan) order, so expiry trims a prefix.
  CellMap<std::vector<Entry>> grid_;
  std::deque<std::pair<long, std::vector<Key>>> touched_;  // cells each remembered scan filled
  std::size_t count_ = 0;
};

}  // namespace cleanmap
