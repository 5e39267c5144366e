// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/map_score.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/error.h"

namespace cleanmap {
namespace {
// Beyond this many cells from the origin a coordinate no longer converts to an integer cell
// safely; masked keys make anything nearer exact (aliased cells only share a bucket).
constexpr double kMaxCells = 1e15;
}  // namespace

bool RadiusIndex::indexable(const Eigen::Vector3f& p) const {
  return p.allFinite() && (p.cast<double>().cwiseAbs() * inv_).maxCoeff() < kMaxCells;
}

RadiusIndex::RadiusIndex(std::vector<Eigen::Vector3f> points, double radius)
    : inv_(1.0 / radius), inv_cell_(0.5 / radius), r2_(static_cast<float>(radius * radius)) {
  if (!(radius > 0)) throw Error("RadiusIndex", "radius must be > 0");
  points.erase(std::remove_if(points.begin(), points.end(),
                              [](const Eigen::Vector3f& p) { return !p.allFinite(); }),
               points.end());
  for (const auto& p : points)
    if (!indexable(p))
      throw Error("RadiusIndex", "a map point lies " + std::to_string(p.norm() / 1000) +
                                     " km from the origin; the index cannot hold it");
  // (key, input index) pairs sorted: cells in key order, each cell's points in input order.
  std::vector<std::pair<uint64_t, uint32_t>> keyed(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    keyed[i] = {
        cellKeyOf(double(points[i].x()), double(points[i].y()), double(points[i].z()), inv_cell_),
        uint32_t(i)};
  std::sort(keyed.begin(), keyed.end());
  std::size_t n_cells = 0;
  for (std::size_t i = 0; i < keyed.size(); ++i)
    n_cells += i == 0 || keyed[i - 1].first != keyed[i].first;
  cells_.reserve(n_cells);
  pts_.reserve(points.size());
  for (std::size_t i = 0, begin = 0; i < keyed.size(); ++i) {
    pts_.push_back(points[keyed[i].second]);
    if (i + 1 == keyed.size() || keyed[i + 1].first != keyed[i].first) {
      cells_.get(keyed[i].first) = {uint32_t(begin), uint32_t(i + 1)};
      begin = i + 1;
    }
  }
}

bool RadiusIndex::hasNeighbour(const Eigen::Vector3f& p) const {
  if (!indexable(p)) return false;
  // A point within radius of p lies within half a cell of it along each axis: in p's cell or in
  // the neighbour on the side of the middle p lies (both where p lies within 1e-3 of a cell of
  // the middle, far more than the rounding of the coordinates and of the distance test; both
  // beyond 1e9 cells from the origin, where the place in the cell is itself rounded).
  constexpr double kHair = 1e-3, kFar = 1e9;
  int64_t c[3];
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    c[a] = floorToCell(double(p[a]), inv_cell_);
    const double t = double(p[a]) * inv_cell_;  // the same product: the place in the cell
    const double f = t - double(c[a]);
    const bool far = std::abs(t) > kFar;
    lo[a] = far || f < 0.5 + kHair ? -1 : 0;
    hi[a] = far || f > 0.5 - kHair ? 1 : 0;
  }
  auto near_in = [&](int dx, int dy, int dz) {
    const auto* cell = cells_.find(cellKey(c[0] + dx, c[1] + dy, c[2] + dz));
    if (!cell) return false;
    for (uint32_t i = cell->first; i < cell->second; ++i)
      if ((pts_[i] - p).squaredNorm() <= r2_) return true;
    return false;
  };
  if (near_in(0, 0, 0)) return true;  // a map point at p itself, the common case
  for (int dx = lo[0]; dx <= hi[0]; ++dx)
    for (int dy = lo[1]; dy <= hi[1]; ++dy)
      for (int dz = lo[2]; dz <= hi[2]; ++dz)
        if ((dx | dy | dz) != 0 && near_in(dx, dy, dz)) return true;
  return false;
}

void RadiusIndex::prefetch(const Eigen::Vector3f& p, bool points) const {
  if (!indexable(p)) return;
  const uint64_t key = cellKeyOf(double(p.x()), double(p.y()), double(p.z()), inv_cell_);
  if (!points) {
    cells_.prefetch(key);
  } else if (const auto* cell = cells_.find(key)) {
    __builtin_prefetch(&pts_[cell->first]);
  }
}

double MapScore::aa() const {
  return std::sqrt(sa() * da());
}
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
