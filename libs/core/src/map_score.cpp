// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/map_score.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "cleanmap/core/error.h"

namespace cleanmap {
namespace {
constexpr int64_t kBias = int64_t(1) << 20;  // 21 bits per axis: +-1M cells (+-50 km at 5 cm)
}

uint64_t RadiusIndex::key(int64_t x, int64_t y, int64_t z) const {
  return (uint64_t(x + kBias) << 42) | (uint64_t(y + kBias) << 21) | uint64_t(z + kBias);
}

RadiusIndex::RadiusIndex(std::vector<Eigen::Vector3f> points, double radius)
    : radius_(radius), r2_(static_cast<float>(radius * radius)) {
  if (!(radius > 0)) throw Error("RadiusIndex", "radius must be > 0");
  const auto cellOf = [&](const Eigen::Vector3f& p) {
    return key(static_cast<int64_t>(std::floor(p.x() / radius_)),
               static_cast<int64_t>(std::floor(p.y() / radius_)),
               static_cast<int64_t>(std::floor(p.z() / radius_)));
  };
  points.erase(std::remove_if(points.begin(), points.end(),
                              [](const Eigen::Vector3f& p) { return !p.allFinite(); }),
               points.end());
  for (const auto& p : points)
    if ((p.cwiseAbs().array() / float(radius_) >= float(kBias - 2)).any())
      throw Error("RadiusIndex", "a map point lies more than " +
                                     std::to_string(int(radius_ * double(kBias) / 1000)) +
                                     " km from the origin; the index cannot hold it");
  std::vector<uint64_t> keys(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) keys[i] = cellOf(points[i]);
  std::vector<uint32_t> order(points.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });
  pts_.reserve(points.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    const uint64_t k = keys[order[i]];
    if (i == 0 || keys[order[i - 1]] != k) cells_[k] = {uint32_t(i), uint32_t(i)};
    cells_[k].second = uint32_t(i + 1);
    pts_.push_back(points[order[i]]);
  }
}

bool RadiusIndex::hasNeighbour(const Eigen::Vector3f& p) const {
  if (!p.allFinite() || (p.cwiseAbs().array() / float(radius_) >= float(kBias - 2)).any()) return false;
  const int64_t cx = static_cast<int64_t>(std::floor(p.x() / radius_));
  const int64_t cy = static_cast<int64_t>(std::floor(p.y() / radius_));
  const int64_t cz = static_cast<int64_t>(std::floor(p.z() / radius_));
  for (int64_t dx = -1; dx <= 1; ++dx)
    for (int64_t dy = -1; dy <= 1; ++dy)
      for (int64_t dz = -1; dz <= 1; ++dz) {
        const auto it = cells_.find(key(cx + dx, cy + dy, cz + dz));
        if (it == cells_.end()) continue;
        for (uint32_t i = it->second.first; i < it->second.second; ++i)
          if ((pts_[i] - p).squaredNorm() <= r2_) return true;
      }
  return false;
}

double MapScore::aa() const { return std::sqrt(sa() * da()); }
double MapScore::ha() const {
  const double s = sa(), d = da();
  return s + d > 0 ? 2.0 * s * d / (s + d) : 0.0;
}
MapScore& MapScore::operator+=(const MapScore& o) {
  static_total += o.static_total;
  static_kept += o.static_kept;
  moving_total += o.moving_total;
  moving_removed += o.moving_removed;
  return *this;
}

void MapScorer::add(const Eigen::Vector3f& p, bool moving) {
  const bool present = map_.hasNeighbour(p);
  if (moving) {
    ++s_.moving_total;
    s_.moving_removed += present ? 0 : 1;
  } else {
    ++s_.static_total;
    s_.static_kept += present ? 1 : 0;
  }
}

}  // namespace cleanmap
