// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/ground.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "cleanmap/core/fast_math.h"
#include "cleanmap/core/median.h"

namespace cleanmap {

std::vector<uint8_t> segmentGround(const std::vector<PointXYZI>& points, const GroundParams& p,
                                   double half_extent, double ground_z) {
  const int n = static_cast<int>(std::ceil(half_extent / p.cell - 0.5));  // cells each side of 0
  const int side = 2 * n + 1;
  const float kInf = std::numeric_limits<float>::infinity();
  std::vector<float> H(static_cast<std::size_t>(side * side), -kInf);
  std::vector<float> h(static_cast<std::size_t>(side * side), kInf);
  std::vector<int> cell_of(points.size(), -1);

  // Cell (0, 0) is centred on the sensor.
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto& q = points[k];
    const int i = static_cast<int>(std::floor(q.x / p.cell + 0.5));
    const int j = static_cast<int>(std::floor(q.y / p.cell + 0.5));
    if (std::abs(i) > n || std::abs(j) > n) continue;
    const int c = (i + n) * side + (j + n);
    cell_of[k] = c;
    H[static_cast<std::size_t>(c)] = std::max(H[static_cast<std::size_t>(c)], q.z);
    h[static_cast<std::size_t>(c)] = std::min(h[static_cast<std::size_t>(c)], q.z);
  }

  std::vector<float> hG(static_cast<std::size_t>(side * side), 0.0f);
  std::vector<int> gap(static_cast<std::size_t>(side * side), 0);  // empty cells crossed
  std::vector<uint8_t> ground_cell(static_cast<std::size_t>(side * side), 0);
  // The highest the ground can lie in a cell: nothing lies below the ground, and it rises by at
  // most s a cell, so a return bounds it there and s a cell further on.
  std::vector<float> ceiling(static_cast<std::size_t>(side * side), kInf);
  auto visit = [&](int i, int j, float hat_h, int hat_gap, float ceiling_in) {
    const auto c = static_cast<std::size_t>((i + n) * side + (j + n));
    const bool has_points = H[c] > -kInf;
    // Eq. (1); across empty cells (the blind zone, shadows) the slope bound s per cell holds for
    // every cell crossed, up to max_gap_cells (our addition: a car on a slope has its blind zone
    // on the slope too). Where only that allowance would lift the cell, its top must also lie
    // within s (its own spread) of the ceiling the returns on the way set: the single ring on a
    // car's hood, a truck's side beside the blind zone or a far walker, beyond the lower returns
    // of the same object, is no road (DESIGN §2a).
    const double rise = p.step * std::min(1 + hat_gap, std::max(1, p.max_gap_cells));
    const float carried = ceiling_in + static_cast<float>(p.step);  // the ceiling here
    const bool ground = has_points && H[c] - h[c] < p.step && H[c] < hat_h + rise &&
                        (H[c] < hat_h + p.step || H[c] < carried + p.step);
    ceiling[c] = std::min(h[c], carried);
    ground_cell[c] = ground;
    hG[c] = ground ? H[c] : hat_h;
    gap[c] = ground ? 0 : hat_gap + (has_points ? 0 : 1);
  };
  visit(0, 0, static_cast<float>(ground_z), 0, kInf);
  for (int ring = 1; ring <= n; ++ring) {
    // The ring's cells only (each reads the inner ring alone, so their order does not matter).
    for (int i = -ring; i <= ring; ++i) {
      const int j_step = std::abs(i) == ring ? 1 : 2 * ring;
      for (int j = -ring; j <= ring; j += j_step) {
        // Neighbours in the inner ring (Chebyshev distance ring-1) propagate to this cell.
        float hat_h = -kInf, ceiling_in = kInf;
        int hat_gap = 0;
        for (int di = -1; di <= 1; ++di)
          for (int dj = -1; dj <= 1; ++dj) {
            const int a = i + di, b = j + dj;
            if (std::max(std::abs(a), std::abs(b)) != ring - 1) continue;
            const auto nb = static_cast<std::size_t>((a + n) * side + (b + n));
            if (hG[nb] > hat_h) hat_h = hG[nb], hat_gap = gap[nb];
            ceiling_in = std::min(ceiling_in, ceiling[nb]);
          }
        visit(i, j, hat_h, hat_gap, ceiling_in);
      }
    }
  }

  // Points of ground cells are ground (Eq. 1). In a cell that is not ground (an object stands
  // in it), the returns within s of the propagated ground height are ground too: the road beside
  // a car's wheel, the foot of a curb.
  std::vector<uint8_t> out(points.size(), 0);
  for (std::size_t k = 0; k < points.size(); ++k) {
    if (cell_of[k] < 0) continue;
    const auto c = static_cast<std::size_t>(cell_of[k]);
    if (ground_cell[c])
      out[k] = kGroundCell;
    else if (p.point_refine && points[k].z < hG[c] + p.step)
      out[k] = kGroundRefined;
  }
  return out;
}

std::optional<double> estimateGroundHeight(const std::vector<PointXYZI>& points) {
  constexpr int kSectors = 36;
  constexpr float kNear2 = 2.0f * 2.0f, kFar2 = 25.0f * 25.0f;
  const float kInf = std::numeric_limits<float>::infinity();
  std::array<std::array<float, 3>, kSectors> low;  // the three lowest z per sector, ascending
  for (auto& l : low) l.fill(kInf);
  for (const auto& q : points) {
    const float r2 = q.x * q.x + q.y * q.y;
    if (!(r2 >= kNear2 && r2 <= kFar2) || !std::isfinite(q.z)) continue;
    // Issue #16: the sector from fast::atan2, libm's where that lies within kEdge of a sector's
    // edge (its error is below 3e-7 rad, 2e-6 of a sector): the same sectors, bit for bit.
    constexpr float kPerRad = float(kSectors / (2 * M_PI)), kEdge = 1e-4f;
    const int s = std::min(
        kSectors - 1, fast::binOrExact((fast::atan2(q.y, q.x) + float(M_PI)) * kPerRad, kEdge, [&] {
          return static_cast<int>((std::atan2(q.y, q.x) + float(M_PI)) * kPerRad);
        }));
    auto& l = low[static_cast<std::size_t>(std::max(0, s))];
    if (q.z >= l[2]) continue;
    l[2] = q.z;
    if (l[2] < l[1]) std::swap(l[2], l[1]);
    if (l[1] < l[0]) std::swap(l[1], l[0]);
  }
  std::vector<float> third;
  for (const auto& l : low)
    if (l[2] < kInf) third.push_back(l[2]);
  if (third.size() < kSectors / 4) return std::nullopt;
  return double(median(std::move(third)));
}

}  // namespace cleanmap
