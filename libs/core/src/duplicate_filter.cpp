// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/duplicate_filter.h"

#include <algorithm>
#include <cmath>

namespace cleanmap {

DuplicateFilter::DuplicateFilter(const FilterParams& p)
    : p_(p), inv_(static_cast<float>(1.0 / p.dup_distance)) {}

DuplicateFilter::Key DuplicateFilter::key(int x, int y, int z) const {
  auto u = [](int v) { return static_cast<uint64_t>(static_cast<uint32_t>(v) & 0x1FFFFFu); };
  return (u(x) << 42) | (u(y) << 21) | u(z);
}

Eigen::Vector3i DuplicateFilter::cell(const Eigen::Vector3f& p) const {
  return {static_cast<int>(std::floor(p.x() * inv_)), static_cast<int>(std::floor(p.y() * inv_)),
          static_cast<int>(std::floor(p.z() * inv_))};
}

bool DuplicateFilter::isDuplicate(const Eigen::Vector3f& p, long scan) const {
  if (grid_.empty()) return false;
  const Eigen::Vector3i c = cell(p);
  const float d2 = static_cast<float>(p_.dup_distance * p_.dup_distance);
  const long oldest = scan - p_.dup_window;
  for (int dx = -1; dx <= 1; ++dx)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dz = -1; dz <= 1; ++dz) {
        const auto it = grid_.find(key(c.x() + dx, c.y() + dy, c.z() + dz));
        if (it == grid_.end()) continue;
        for (const Entry& e : it->second)
          if (e.scan >= oldest && e.scan < scan && (e.p - p).squaredNorm() <= d2) return true;
      }
  return false;
}

void DuplicateFilter::insert(const std::vector<Eigen::Vector3f>& points, long scan) {
  for (const auto& p : points) {
    const Eigen::Vector3i c = cell(p);
    grid_[key(c.x(), c.y(), c.z())].push_back({p, scan});
  }
  count_ += points.size();
  prune(scan + 1 - p_.dup_window);
}

void DuplicateFilter::prune(long oldest) {
  for (auto it = grid_.begin(); it != grid_.end();) {
    auto& v = it->second;
    const std::size_t before = v.size();
    v.erase(std::remove_if(v.begin(), v.end(), [&](const Entry& e) { return e.scan < oldest; }),
            v.end());
    count_ -= before - v.size();
    it = v.empty() ? grid_.erase(it) : std::next(it);
  }
}

}  // namespace cleanmap
