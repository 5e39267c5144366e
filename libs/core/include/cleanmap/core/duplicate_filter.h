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

  // One bit per hashed cell key, set where a cell holds entries (issue #16): a query's empty
  // neighbour cells, most of those of a point that is not a duplicate, are rejected by a bit in
  // 128 KiB (cache resident) instead of a probe of the grid's table. A set bit may be another
  // cell's (hash collision): the grid then answers; a clear bit is always right.
  static constexpr std::size_t kOccupancyBits = std::size_t(1) << 20;
  static std::size_t occupancyBit(uint64_t key) {
    return static_cast<std::size_t>((key * 0xD6E8FEB86659FD93ull) >> 44);
  }
  bool mayHold(uint64_t key) const {
    const std::size_t b = occupancyBit(key);
    return (occupied_[b >> 6] >> (b & 63)) & 1u;
  }
  std::vector<uint64_t> occupied_ = std::vector<uint64_t>(kOccupancyBits / 64, 0);

  FilterParams p_;
  float inv_;  // cells of side 2 d_dup: a query ball touches at most 2 x 2 x 2 of them
  // Entries of a cell are in insertion (= scan) order, so expiry trims a prefix.
  CellMap<std::vector<Entry>> grid_;
  std::deque<std::pair<long, std::vector<Key>>> touched_;  // cells each remembered scan filled
  std::size_t count_ = 0;
};

}  // namespace cleanmap
