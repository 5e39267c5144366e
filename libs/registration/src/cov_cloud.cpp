// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/registration/cov_cloud.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <numeric>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/parallel.h"

namespace cleanmap::reg {

std::vector<uint32_t> voxelDownsample(const std::vector<Eigen::Vector3d>& points, double voxel) {
  const double inv = 1.0 / voxel;
  CellMap<uint8_t> taken;  // the voxels that have their first point
  taken.reserve(points.size());
  std::vector<uint32_t> out;
  for (uint32_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    if (taken.insert(cellKeyOf(p.x(), p.y(), p.z(), inv))) out.push_back(i);
  }
  return out;
}

std::vector<Eigen::Matrix3d> planeCovariances(const std::vector<Eigen::Vector3d>& points, int knn,
                                              double radius, double eps, int threads) {
  // Cells of side `radius`: the neighbours within radius lie in the 27 cells around a point.
  const double inv = 1.0 / radius, r2 = radius * radius;
  // Points sorted by cell (ties in input order); a cell is a range [begin, end) of `order`.
  std::vector<uint64_t> key(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    key[i] = cellKeyOf(points[i].x(), points[i].y(), points[i].z(), inv);
  std::vector<uint32_t> order(points.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(),
            [&](uint32_t a, uint32_t b) { return key[a] != key[b] ? key[a] < key[b] : a < b; });
  CellMap<uint32_t> begin_of;
  begin_of.reserve(points.size());
  std::vector<uint32_t> cell_end(points.size() + 1, 0);  // by begin position
  for (uint32_t k = 0; k < order.size(); ++k) {
    bool fresh = false;
    uint32_t& b = begin_of.get(key[order[k]], &fresh);
    if (fresh) b = k;
    cell_end[b] = k + 1;
  }
  std::vector<Eigen::Matrix3d> covs(points.size());
  const std::size_t k = static_cast<std::size_t>(std::max(knn, 3));
  std::vector<std::vector<std::pair<double, uint32_t>>> scratch(
      static_cast<std::size_t>(std::max(threads, 1)));
  // The points of one cell share their 27 neighbour cells: those are looked up once per cell
  // (issue #16), and every point still meets its candidates in the same order as before.
  std::vector<uint32_t> cells;  // each cell's begin position in `order`
  for (uint32_t pos = 0; pos < order.size(); pos = cell_end[pos]) cells.push_back(pos);
  parallelFor(
      cells.size(), threads,
      [&](std::size_t ci, int worker) {
        auto& near = scratch[static_cast<std::size_t>(worker)];
        const uint32_t cb = cells[ci];
        const uint64_t c = key[order[cb]];
        std::array<std::pair<uint32_t, uint32_t>, 27> ranges;
        std::size_t nr = 0;
        forEachNeighbour27([&](int dx, int dy, int dz) {
          const uint32_t* b = begin_of.find(cellKeyShift(c, dx, dy, dz));
          if (b) ranges[nr++] = {*b, cell_end[*b]};
        });
        for (uint32_t at = cb; at < cell_end[cb]; ++at) {
          const uint32_t i = order[at];
          near.clear();
          const Eigen::Vector3d& p = points[i];
          for (std::size_t r = 0; r < nr; ++r)
            for (uint32_t pos = ranges[r].first; pos < ranges[r].second; ++pos) {
              const uint32_t j = order[pos];
              const double d2 = (points[j] - p).squaredNorm();
              if (d2 <= r2) near.emplace_back(d2, j);
            }
          if (near.size() > k) {
            std::nth_element(near.begin(), near.begin() + static_cast<long>(k), near.end());
            near.resize(k);
          }
          if (near.size() < 5) {
            covs[i] = Eigen::Matrix3d::Identity();
            continue;
          }
          Eigen::Vector3d mean = Eigen::Vector3d::Zero();
          for (const auto& [d2, j] : near) mean += points[j];
          mean /= static_cast<double>(near.size());
          Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
          for (const auto& [d2, j] : near) {
            const Eigen::Vector3d d = points[j] - mean;
            C += d * d.transpose();
          }
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
          es.computeDirect(C / static_cast<double>(near.size()));
          const Eigen::Matrix3d& V = es.eigenvectors();  // increasing eigenvalues
          covs[i] = V * Eigen::Vector3d(eps, 1.0, 1.0).asDiagonal() * V.transpose();
        }
      },
      64);
  return covs;
}

}  // namespace cleanmap::reg
