// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/duplicate_filter.h"

#include <algorithm>
#include <cmath>

#include "cleanmap/core/cell_key.h"

namespace cleanmap {

DuplicateFilter::DuplicateFilter(const FilterParams& p)
    : p_(p), inv_(static_cast<float>(0.5 / p.dup_distance)) {}

bool DuplicateFilter::isDuplicate(const Eigen::Vector3f& p, long scan) const {
  if (grid_.empty()) return false;
  // With cells of side 2d, the ball of radius d around p reaches one neighbour per axis: the one
  // on the side of the cell's half that p lies in.
  int lo[3], home[3];  // home: 1 where p's own cell is lo + 1
  for (int a = 0; a < 3; ++a) {
    const float u = p[a] * inv_;
    const float c = std::floor(u);
    home[a] = u - c < 0.5f ? 1 : 0;
    lo[a] = static_cast<int>(c) - home[a];
  }
  const float d2 = static_cast<float>(p_.dup_distance * p_.dup_distance);
  const long oldest = scan - p_.dup_window;
  // p's own cell first: most duplicates lie there, and the answer does not depend on the order.
  for (int m = 0; m < 8; ++m) {
    const uint64_t key = cellKey(lo[0] + (home[0] ^ (m & 1)), lo[1] + (home[1] ^ (m >> 1 & 1)),
                                 lo[2] + (home[2] ^ (m >> 2)));
    if (!mayHold(key)) continue;  // most neighbours of a new point are empty
    const auto* cell = grid_.find(key);
    if (!cell) continue;
    for (const Entry& e : *cell)
      if (e.scan >= oldest && e.scan < scan && (e.p - p).squaredNorm() <= d2) return true;
  }
  return false;
}

void DuplicateFilter::insert(const std::vector<Eigen::Vector3f>& points, long scan) {
  std::vector<Key> keys;
  keys.reserve(points.size());
  for (const auto& p : points) {
    const Key k = cellKeyOf(p.x(), p.y(), p.z(), inv_);
    grid_[k].push_back({p, static_cast<int32_t>(scan)});
    keys.push_back(k);
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  touched_.emplace_back(scan, std::move(keys));
  count_ += points.size();
  prune(scan + 1 - p_.dup_window);
  // The occupancy bits, from the cells left (a few tens of thousands: microseconds).
  occupied_.assign(kOccupancyBits / 64, 0);
  grid_.forEach([&](uint64_t k, const std::vector<Entry>&) {
    const std::size_t b = occupancyBit(k);
    occupied_[b >> 6] |= uint64_t(1) << (b & 63);
  });
}

void DuplicateFilter::prune(long oldest) {
  // Only the cells the expiring scans filled can hold expired entries: O(expired points).
  while (!touched_.empty() && touched_.front().first < oldest) {
    for (const Key k : touched_.front().second) {
      auto* v = grid_.find(k);
      if (!v) continue;
      const auto keep =
          std::find_if(v->begin(), v->end(), [&](const Entry& e) { return e.scan >= oldest; });
      count_ -= static_cast<std::size_t>(keep - v->begin());
      v->erase(v->begin(), keep);
      if (v->empty()) grid_.erase(k);
    }
    touched_.pop_front();
  }
}

}  // namespace cleanmap
