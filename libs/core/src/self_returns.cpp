// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.2, "Self returns" (self_returns.h).
#include "cleanmap/core/self_returns.h"

#include <cmath>

#include "cleanmap/core/beam_index.h"
#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/cell_map.h"

namespace cleanmap {

std::size_t findSelfReturns(const std::vector<PointXYZI>& points,
                            const std::vector<uint8_t>& member, const std::vector<uint8_t>& flagged,
                            const Eigen::Vector3d& sensor_at, const std::vector<WindowScan>& window,
                            double range, double voxel, std::vector<uint8_t>& self) {
  self.assign(points.size(), 0);
  if (!(range > 0) || !(voxel > 0)) return 0;
  std::vector<const BeamIndex*> compared;
  for (const WindowScan& w : window)
    if (w.beams &&
        (w.world_to_sensor.inverse().translation() - sensor_at).norm() >= SelfReturns::kTravel)
      compared.push_back(w.beams);
  if (compared.size() < static_cast<std::size_t>(SelfReturns::kMinScans)) return 0;
  const auto r = static_cast<float>(range);
  const auto near = [&](std::size_t i) { return points[i].xyz().head<2>().norm() < r; };
  bool any = false;
  for (std::size_t i = 0; i < points.size() && !any; ++i) any = member[i] && flagged[i] && near(i);
  if (!any) return 0;
  // The member voxels near the range: 1 within it, 2 holding a point beyond it.
  const float inv = static_cast<float>(1.0 / voxel), margin = 2.0f * static_cast<float>(voxel);
  const auto cell = [&](const Eigen::Vector3f& x) {
    return Eigen::Vector3i(static_cast<int>(floorToCell(x.x(), inv)),
                           static_cast<int>(floorToCell(x.y(), inv)),
                           static_cast<int>(floorToCell(x.z(), inv)));
  };
  CellMap<uint8_t> voxels;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!member[i]) continue;
    const float h = points[i].xyz().head<2>().norm();
    if (h >= r + margin) continue;
    const Eigen::Vector3i c = cell(points[i].xyz());
    uint8_t& v = voxels.get(cellKey(c.x(), c.y(), c.z()));
    v = std::max<uint8_t>(v, h < r ? 1 : 2);
  }
  // Per voxel reached: 1 its component lies within the range, 2 it does not (searched until a
  // voxel beyond it is met).
  CellMap<uint8_t> within;
  std::vector<Eigen::Vector3i> stack, seen;
  const auto isolated = [&](const Eigen::Vector3i& start) {
    if (const uint8_t* known = within.find(cellKey(start.x(), start.y(), start.z())))
      return *known == 1;
    if (const uint8_t* v = voxels.find(cellKey(start.x(), start.y(), start.z())); v && *v == 2)
      return false;
    stack.assign(1, start);
    seen.assign(1, start);
    within.get(cellKey(start.x(), start.y(), start.z())) = 1;
    bool inside = true;
    while (!stack.empty() && inside) {
      const Eigen::Vector3i c = stack.back();
      stack.pop_back();
      for (int dx = -1; dx <= 1 && inside; ++dx)
        for (int dy = -1; dy <= 1 && inside; ++dy)
          for (int dz = -1; dz <= 1 && inside; ++dz) {
            const Eigen::Vector3i n(c.x() + dx, c.y() + dy, c.z() + dz);
            const uint8_t* v = voxels.find(cellKey(n.x(), n.y(), n.z()));
            if (!v) continue;
            if (*v == 2) {
              inside = false;
              break;
            }
            bool inserted = false;
            uint8_t& mark = within.get(cellKey(n.x(), n.y(), n.z()), &inserted);
            if (!inserted) {  // this search's, or one that met the range's edge
              inside = mark == 1;
              continue;
            }
            mark = 1;
            stack.push_back(n);
            seen.push_back(n);
          }
    }
    if (!inside)
      for (const Eigen::Vector3i& c : seen) within.get(cellKey(c.x(), c.y(), c.z())) = 2;
    return inside;
  };
  const double tol2 = SelfReturns::kTolerance * SelfReturns::kTolerance;
  const auto need = static_cast<std::size_t>(std::ceil(SelfReturns::kShare * compared.size()));
  std::size_t marked = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!member[i] || !flagged[i] || !near(i) || !isolated(cell(points[i].xyz()))) continue;
    const Eigen::Vector3f x = points[i].xyz();
    const double d = x.norm();
    if (!(d > SelfReturns::kTolerance)) continue;
    const Eigen::Vector3f dir = (x / static_cast<float>(d)).eval();
    const double cone = std::asin(SelfReturns::kTolerance / d);
    std::size_t stays = 0;
    for (std::size_t j = 0; j < compared.size() && stays < need; ++j) {
      if (stays + (compared.size() - j) < need) break;
      bool found = false;
      compared[j]->forEachNear(dir, cone, [&](const BeamIndex::Beam& b) {
        found = found || (b.dir * b.range - x).squaredNorm() < tol2;
      });
      stays += found;
    }
    if (stays >= need) {
      self[i] = 1;
      ++marked;
    }
  }
  return marked;
}

}  // namespace cleanmap
