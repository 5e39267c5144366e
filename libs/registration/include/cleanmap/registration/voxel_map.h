// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.1: the local map GICP aligns to — world points with their covariances in a voxel hash
// (at most `max_per_voxel` per voxel), searched in the 27 voxels around a query. Each entry
// remembers the scan and point it came from, so the points the pipeline later decides moving can
// be taken out again, and the map forgets what lies beyond a radius of the sensor. Scans come in
// order, so a voxel's entries are in scan order and a search can leave out the newest scans.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <vector>

#include "cleanmap/core/cell_map.h"
#include "cleanmap/registration/cov_cloud.h"

namespace cleanmap::reg {

class VoxelMap {
 public:
  /// A match of nearest(): the entry's position and covariance.
  struct Match {
    const Eigen::Vector3d* p = nullptr;
    const Eigen::Matrix3d* cov = nullptr;
    explicit operator bool() const { return p != nullptr; }
  };

  VoxelMap(double voxel, int max_per_voxel);

  /// Adds a cloud already in the world frame (covariances too), tagged with its scan; scans come
  /// in non-decreasing order (std::invalid_argument otherwise).
  void insert(const CovCloud& world, int64_t scan);
  /// Removes the entries of `scan` whose point index is flagged in `drop` (indexed by point).
  void remove(int64_t scan, const std::vector<uint8_t>& drop);
  /// Forgets voxels farther than `radius` from `centre` (horizontally and vertically alike).
  void prune(const Eigen::Vector3d& centre, double radius);
  /// The nearest entry within `max_dist` (<= voxel) of p among those of scans up to
  /// `newest_scan`; empty if none. Neighbour voxels are visited only while their box is nearer
  /// than the best match so far.
  Match nearest(const Eigen::Vector3d& p, double max_dist, int64_t newest_scan = INT64_MAX) const;

  std::size_t size() const { return count_; }
  bool empty() const { return count_ == 0; }
  double voxel() const { return voxel_; }

 private:
  double voxel_, inv_;
  std::size_t max_per_voxel_;
  // Positions apart from the rest, so a search reads 24 bytes per candidate.
  struct Voxel {
    std::vector<Eigen::Vector3d> p;
    std::vector<Eigen::Matrix3d> cov;
    std::vector<std::pair<int64_t, uint32_t>> origin;  // (scan, point)
  };
  // A flat table (issue #16): a query probes up to 27 voxels, one cache line each instead of a
  // bucket and a node; the entries' order within a voxel is their insertion order.
  CellMap<Voxel> grid_;
  std::deque<std::pair<int64_t, std::vector<uint64_t>>> touched_;  // voxels each scan filled
  std::size_t count_ = 0;
  int64_t last_scan_ = INT64_MIN;  // the scan inserted last
};

}  // namespace cleanmap::reg
