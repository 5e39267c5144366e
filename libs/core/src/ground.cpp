// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/ground.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cleanmap {

std::vector<uint8_t> segmentGround(const std::vector<PointXYZI>& points, const GroundParams& p,
                                   double half_extent) {
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
  std::vector<uint8_t> ground_cell(static_cast<std::size_t>(side * side), 0);
  auto visit = [&](int i, int j, float hat_h) {
    const auto c = static_cast<std::size_t>((i + n) * side + (j + n));
    const bool has_points = H[c] > -kInf;
    const bool ground = has_points && H[c] - h[c] < p.step && H[c] < hat_h + p.step;  // Eq. (1)
    ground_cell[c] = ground;
    hG[c] = ground ? H[c] : hat_h;
  };
  visit(0, 0, static_cast<float>(p.sensor_height));
  for (int ring = 1; ring <= n; ++ring) {
    for (int i = -ring; i <= ring; ++i) {
      for (int j = -ring; j <= ring; ++j) {
        if (std::max(std::abs(i), std::abs(j)) != ring) continue;
        // Neighbours in the inner ring (Chebyshev distance ring-1) propagate to this cell.
        float hat_h = -kInf;
        for (int di = -1; di <= 1; ++di)
          for (int dj = -1; dj <= 1; ++dj) {
            const int a = i + di, b = j + dj;
            if (std::max(std::abs(a), std::abs(b)) != ring - 1) continue;
            hat_h = std::max(hat_h, hG[static_cast<std::size_t>((a + n) * side + (b + n))]);
          }
        visit(i, j, hat_h);
      }
    }
  }

  std::vector<uint8_t> out(points.size(), 0);
  for (std::size_t k = 0; k < points.size(); ++k)
    out[k] = cell_of[k] >= 0 && ground_cell[static_cast<std::size_t>(cell_of[k])];
  return out;
}

}  // namespace cleanmap
