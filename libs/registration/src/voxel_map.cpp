// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/registration/voxel_map.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "cleanmap/core/cell_key.h"

namespace cleanmap::reg {

VoxelMap::VoxelMap(double voxel, int max_per_voxel)
    : voxel_(voxel),
      inv_(1.0 / voxel),
      max_per_voxel_(static_cast<std::size_t>(std::max(1, max_per_voxel))) {}

void VoxelMap::insert(const CovCloud& world, int64_t scan) {
  if (scan < last_scan_)
    throw std::invalid_argument("VoxelMap::insert: scan " + std::to_string(scan) + " after scan " +
                                std::to_string(last_scan_) + " (scans come in order)");
  last_scan_ = scan;
  std::vector<uint64_t> keys;
  for (std::size_t i = 0; i < world.size(); ++i) {
    const Eigen::Vector3d& p = world.points[i];
    const uint64_t k = cellKeyOf(p.x(), p.y(), p.z(), inv_);
    auto& v = grid_[k];
    if (v.p.size() >= max_per_voxel_) continue;  // full: the voxel is already well described
    v.p.push_back(p);
    v.cov.push_back(world.covs[i]);
    v.origin.emplace_back(scan, world.source.empty() ? uint32_t(i) : world.source[i]);
    keys.push_back(k);
    ++count_;
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  touched_.emplace_back(scan, std::move(keys));
  while (touched_.size() > 64) touched_.pop_front();  // removals come within the pipeline's delay
}

void VoxelMap::remove(int64_t scan, const std::vector<uint8_t>& drop) {
  for (const auto& [s, keys] : touched_) {
    if (s != scan) continue;
    for (const uint64_t k : keys) {
      Voxel* found = grid_.find(k);
      if (!found) continue;
      Voxel& v = *found;
      std::size_t kept = 0;
      for (std::size_t e = 0; e < v.p.size(); ++e) {
        const auto [s2, point] = v.origin[e];
        if (s2 == scan && point < drop.size() && drop[point]) continue;
        v.p[kept] = v.p[e];
        v.cov[kept] = v.cov[e];
        v.origin[kept] = v.origin[e];
        ++kept;
      }
      count_ -= v.p.size() - kept;
      v.p.resize(kept);
      v.cov.resize(kept);
      v.origin.resize(kept);
      if (kept == 0) grid_.erase(k);
    }
  }
}

void VoxelMap::prune(const Eigen::Vector3d& centre, double radius) {
  const double r2 = radius * radius;
  std::vector<uint64_t> far;  // erased after the walk: an erase shifts later slots back
  grid_.forEach([&](uint64_t k, const Voxel& v) {
    if (!v.p.empty() && (v.p.front() - centre).squaredNorm() > r2) far.push_back(k);
  });
  for (const uint64_t k : far) {
    count_ -= grid_.find(k)->p.size();
    grid_.erase(k);
  }
}

VoxelMap::Match VoxelMap::nearest(const Eigen::Vector3d& p, double max_dist,
                                  int64_t newest_scan) const {
  Match best;
  double best2 = max_dist * max_dist;
  const Eigen::Vector3d u = p * inv_;
  const Eigen::Vector3d cell(std::floor(u.x()), std::floor(u.y()), std::floor(u.z()));
  const Eigen::Vector3d f = (u - cell) * voxel_;  // position inside the voxel, metres
  const uint64_t c = cellKey(static_cast<int64_t>(cell.x()), static_cast<int64_t>(cell.y()),
                             static_cast<int64_t>(cell.z()));
  // Entries are in scan order: those of scans after newest_scan are at the end. Where no entry is
  // that new, their origins are not read (a cache miss per voxel, issue #16).
  const bool trim = newest_scan < last_scan_;
  auto scan = [&](uint64_t key) {
    const Voxel* found = grid_.find(key);
    if (!found) return;
    const Voxel& v = *found;
    std::size_t n = v.p.size();
    if (trim)
      while (n > 0 && v.origin[n - 1].first > newest_scan) --n;
    for (std::size_t e = 0; e < n; ++e) {
      const double d2 = (v.p[e] - p).squaredNorm();
      if (d2 < best2) best2 = d2, best = Match{&v.p[e], &v.cov[e]};
    }
  };
  scan(c);  // the own voxel first: its match bounds which neighbours can hold a nearer one
  // With max_dist <= voxel, every candidate lies in the 27 voxels around p; a neighbour is read
  // only if the distance from p to its box is below the best so far.
  forEachNeighbour27([&](int dx, int dy, int dz) {
    if (dx == 0 && dy == 0 && dz == 0) return;
    double box2 = 0;
    const int d[3] = {dx, dy, dz};
    for (int a = 0; a < 3; ++a) {
      const double gap = d[a] < 0 ? f[a] : d[a] > 0 ? voxel_ - f[a] : 0.0;
      box2 += gap * gap;
    }
    if (box2 < best2) scan(cellKeyShift(c, dx, dy, dz));
  });
  return best;
}

}  // namespace cleanmap::reg
