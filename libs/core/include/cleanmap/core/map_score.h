// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §5: clean-map scores of the DynamicMap benchmark (SA, DA, AA, HA). A ground-truth point is
// kept if the scored map has a point within `radius` (0.05 m) of it.
#pragma once
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "cleanmap/core/cell_map.h"

namespace cleanmap {

/// Exact fixed-radius neighbour test over a static cloud: points sorted into cubic cells of side
/// 2 `radius`, so a query looks at its own cell and, per axis, the neighbour on the side of the
/// cell it lies in (8 cells, its own first; both neighbours within a hair of the middle). Memory:
/// the points plus one entry per cell.
class RadiusIndex {
 public:
  RadiusIndex(std::vector<Eigen::Vector3f> points, double radius);
  /// True iff some indexed point q has |q - p| <= radius.
  bool hasNeighbour(const Eigen::Vector3f& p) const;
  /// A hint that p will be asked soon; answers never change. The test waits on two loads from
  /// memory, its cell's table slot and then the cell's first point (`perf annotate`: 72 % of its
  /// time), so a caller going through many points hints each twice (prefetchAhead): kSlotAhead
  /// queries ahead (`points` false: the slot starts loading) and kPointAhead ahead (true: the slot
  /// is in cache by then, the point starts loading).
  void prefetch(const Eigen::Vector3f& p, bool points) const;
  static constexpr std::size_t kSlotAhead = 16, kPointAhead = 8;
  /// Both hints for the queries ahead of query i of n; at(k) is query k (a point).
  template <class At>
  void prefetchAhead(std::size_t i, std::size_t n, const At& at) const {
    if (i + kSlotAhead < n) prefetch(at(i + kSlotAhead), false);
    if (i + kPointAhead < n) prefetch(at(i + kPointAhead), true);
  }
  std::size_t size() const { return pts_.size(); }
  const std::vector<Eigen::Vector3f>& points() const {
    return pts_;
  }  ///< finite input points, cell order

 private:
  bool indexable(const Eigen::Vector3f& p) const;
  std::vector<Eigen::Vector3f> pts_;              // sorted by cell
  CellMap<std::pair<uint32_t, uint32_t>> cells_;  // key -> [begin, end)
  double inv_, inv_cell_;                         // 1 / radius, 1 / (2 radius)
  float r2_;
};

struct MapScore {
  uint64_t static_total = 0, static_kept = 0;
  uint64_t moving_total = 0, moving_removed = 0;
  /// Static accuracy: share of ground-truth static points the map keeps.
  double sa() const { return static_total ? double(static_kept) / double(static_total) : 0.0; }
  /// Dynamic accuracy: share of ground-truth moving points the map does not contain.
  double da() const { return moving_total ? double(moving_removed) / double(moving_total) : 0.0; }
  double aa() const;  ///< sqrt(SA * DA)
  double ha() const;  ///< 2 SA DA / (SA + DA), 0 when both are 0
  MapScore& operator+=(const MapScore& o);
};

/// Scores ground-truth points (world frame) against the map index, one point at a time, so the
/// ground-truth union never has to be held in memory.
class MapScorer {
 public:
  explicit MapScorer(const RadiusIndex& map) : map_(map) {}
  void add(const Eigen::Vector3f& p, bool moving);
  /// RadiusIndex::prefetchAhead for the points to be added soon.
  template <class At>
  void prefetchAhead(std::size_t i, std::size_t n, const At& at) const {
    map_.prefetchAhead(i, n, at);
  }
  const MapScore& score() const { return s_; }

 private:
  const RadiusIndex& map_;
  MapScore s_;
};

/// Object-level grade of paper Table II: f = share of an object's moving points labelled moving.
enum class ObjectGrade { kDetected, kPartial, kMissed };
inline ObjectGrade gradeObject(double f) {
  return f >= 0.9 ? ObjectGrade::kDetected
                  : (f >= 0.1 ? ObjectGrade::kPartial : ObjectGrade::kMissed);
}

}  // namespace cleanmap
