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
  // The member voxels near the range: 1 within it, 2 holding a point beyond it.
  const float inv = static_cast<float>(1.0 / voxel), margin = 2.0f * static_cast<float>(voxel);
  const auto cell = [&](const Eigen::Vector3f& x) { return cellKeyOf(x.x(), x.y(), x.z(), inv); };
  CellMap<uint8_t> voxels;
  bool any = false;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!member[i]) continue;
    const float h = points[i].xyz().head<2>().norm();
    if (h >= r + margin) continue;
    any = any || (flagged[i] && h < r);
    uint8_t& v = voxels.get(cell(points[i].xyz()));
    v = std::max<uint8_t>(v, h < r ? 1 : 2);
  }
  if (!any) return 0;
  // Per voxel reached: 1 its component lies within the range, 2 it does not (searched until a
  // voxel beyond it is met).
  CellMap<uint8_t> within;
  std::vector<uint64_t> stack, seen;
  const auto isolated = [&](uint64_t start) {
    if (const uint8_t* known = within.find(start)) return *known == 1;
    if (const uint8_t* v = voxels.find(start); v && *v == 2) return false;
    stack.assign(1, start);
    seen.assign(1, start);
    within.get(start) = 1;
    bool inside = true;
    while (!stack.empty() && inside) {
      const uint64_t c = stack.back();
      stack.pop_back();
      forEachNeighbour27([&](int dx, int dy, int dz) {
        if (!inside) return;
        const uint64_t n = cellKeyShift(c, dx, dy, dz);
        const uint8_t* v = voxels.find(n);
        if (!v) return;
        if (*v == 2) {
          inside = false;
          return;
        }
        bool inserted = false;
        uint8_t& mark = within.get(n, &inserted);
        if (!inserted) {  // this search's, or one that met the range's edge
          inside = mark == 1;
          return;
        }
        mark = 1;
        stack.push_back(n);
        seen.push_back(n);
      });
    }
    if (!inside)
      for (const uint64_t c : seen) within.get(c) = 2;
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
