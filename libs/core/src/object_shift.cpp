// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/object_shift.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cleanmap {

namespace {

// Per grid cell, the lowest and highest point in it; `span` says which cells reach min_span.
struct Heights {
  std::vector<float> lo, hi;
  void reset(std::size_t n) {
    lo.assign(n, std::numeric_limits<float>::infinity());
    hi.assign(n, -std::numeric_limits<float>::infinity());
  }
  void add(std::size_t c, float z) {
    lo[c] = std::min(lo[c], z);
    hi[c] = std::max(hi[c], z);
  }
  bool span(std::size_t c, float min_span) const { return hi[c] - lo[c] >= min_span; }
};

// The spread of n points from their sums (cell units): the variances a (x), d (y), b (x y), and
// its eigenvalues, `along` its main axis and `across` it.
struct Spread {
  double a, d, b, along, across;
};
Spread spreadOf(double n, double sx, double sy, double sxx, double syy, double sxy) {
  const double a = sxx / n - (sx / n) * (sx / n), d = syy / n - (sy / n) * (sy / n);
  const double b = sxy / n - (sx / n) * (sy / n);
  const double mid = 0.5 * (a + d), r = std::sqrt(0.25 * (a - d) * (a - d) + b * b);
  return {a, d, b, mid + r, mid - r};
}

// OutlineShift::side and its ends (doc/OBJECTS.md rule 7, "A side's ends"). `cells`: the
// object's outline cells; `mine`, `theirs`: 1 on the object's and the target's outline cells;
// `at(q, x, y)`: q's cell, false outside the grid (whose margin is the reach and two cells).
template <class At>
void sideEnds(const std::vector<Eigen::Vector3f>& object,
              const std::vector<Eigen::Vector3f>& target, const std::vector<int>& cells,
              const std::vector<uint8_t>& mine, const std::vector<uint8_t>& theirs, int w,
              const Eigen::Vector2f& origin, float cell, float reach, At&& at, OutlineShift& out) {
  if (cells.size() < 3) return;
  // The line through the cells' centres (cell units): the larger axis of their spread.
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (const int c : cells) {
    const double x = c % w, y = c / w;
    sx += x, sy += y, sxx += x * x, syy += y * y, sxy += x * y;
  }
  const double n = static_cast<double>(cells.size()), mx = sx / n, my = sy / n;
  const Spread f = spreadOf(n, sx, sy, sxx, syy, sxy);
  if (f.across > 1.0) return;  // spread across over a cell: not one straight side
  Eigen::Vector2d u = std::abs(f.b) > 1e-12
                          ? Eigen::Vector2d(f.b, f.along - f.a)
                          : (f.a >= f.d ? Eigen::Vector2d(1, 0) : Eigen::Vector2d(0, 1));
  u.normalize();
  if (u.x() < 0 || (u.x() == 0 && u.y() < 0)) u = -u;
  out.side = u.cast<float>();
  // Along and across the line, in metres, of a point in an outline cell of `on`.
  const Eigen::Vector2f centre = origin + Eigen::Vector2f((static_cast<float>(mx) + 0.5f) * cell,
                                                          (static_cast<float>(my) + 0.5f) * cell);
  const float band = 2 * cell, gap = 3 * cell;
  const auto place = [&](const Eigen::Vector3f& q, const std::vector<uint8_t>& on, float& t) {
    int x, y;
    if (!at(q, x, y) || on[static_cast<std::size_t>(y) * w + x] != 1) return false;
    const Eigen::Vector2f v = q.head<2>() - centre;
    t = v.dot(out.side);
    return std::abs(v.x() * out.side.y() - v.y() * out.side.x()) <= band;
  };
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  std::vector<float> t_object(object.size(), std::numeric_limits<float>::quiet_NaN());
  for (std::size_t i = 0; i < object.size(); ++i) {
    float t;
    if (!place(object[i], mine, t)) continue;
    t_object[i] = t;
    lo = std::min(lo, t), hi = std::max(hi, t);
  }
  if (!(lo <= hi)) return;
  std::vector<std::pair<float, uint32_t>> line;  // the target's points on it, by t
  for (uint32_t i = 0; i < target.size(); ++i) {
    float t;
    if (place(target[i], theirs, t)) line.emplace_back(t, i);
  }
  std::sort(line.begin(), line.end());
  // The target's stretch: from its points beside the object's, on while the gaps are small.
  std::size_t first = 0;
  while (first < line.size() && line[first].first < lo) ++first;
  if (first == line.size() || line[first].first > hi) return;
  std::size_t last = first;
  while (last + 1 < line.size() && line[last + 1].first <= hi) ++last;
  while (last + 1 < line.size() && line[last + 1].first - line[last].first <= gap) ++last;
  while (first > 0 && line[first].first - line[first - 1].first <= gap) --first;
  const float ends[2][2] = {{lo, line[first].first}, {hi, line[last].first}};
  for (int e = 0; e < 2; ++e) {
    const float mine_end = ends[e][0], theirs_end = ends[e][1], sign = e ? 1.0f : -1.0f;
    const float beyond = sign * (theirs_end - mine_end);  // > 0: the target's runs on further
    if (beyond > reach) continue;
    out.end_shift[e] = theirs_end - mine_end;
    if (beyond > cell) {
      for (std::size_t k = first; k <= last; ++k)
        if (sign * (line[k].first - mine_end) > cell) out.end_target[e].push_back(line[k].second);
    } else if (-beyond > cell) {
      for (uint32_t i = 0; i < object.size(); ++i)
        if (sign * (t_object[i] - theirs_end) > cell) out.end_object[e].push_back(i);
    }
  }
}

}  // namespace

OutlineShift outlineShift(const std::vector<Eigen::Vector3f>& object,
                          const std::vector<Eigen::Vector3f>& target, const ShiftParams& p) {
  OutlineShift out;
  if (object.empty()) return out;
  Eigen::Vector2f lo = object.front().head<2>(), hi = lo;
  for (const auto& q : object) lo = lo.cwiseMin(q.head<2>()), hi = hi.cwiseMax(q.head<2>());
  const float cell = static_cast<float>(p.cell), min_span = static_cast<float>(p.min_span);
  const int reach = std::max(1, static_cast<int>(std::lround(p.reach / p.cell)));
  const int margin = reach + 2;  // the shifted outline and its 3 x 3 stay inside the grid
  const Eigen::Vector2f origin = lo - Eigen::Vector2f::Constant(margin * cell);
  const int w = static_cast<int>((hi.x() - lo.x()) / cell) + 2 * margin + 1;
  const int h = static_cast<int>((hi.y() - lo.y()) / cell) + 2 * margin + 1;
  const std::size_t size = static_cast<std::size_t>(w) * h;
  const auto at = [&](const Eigen::Vector3f& q, int& x, int& y) {
    x = static_cast<int>(std::floor((q.x() - origin.x()) / cell));
    y = static_cast<int>(std::floor((q.y() - origin.y()) / cell));
    return x >= 1 && y >= 1 && x < w - 1 && y < h - 1;
  };
  // The outline cells of a cloud (those spanning min_span), each once, in the order first met.
  Heights z;
  const auto outlineOf = [&](const std::vector<Eigen::Vector3f>& points) {
    z.reset(size);
    std::vector<int> filled, outline;
    for (const auto& q : points) {
      int x, y;
      if (!at(q, x, y)) continue;
      const int c = y * w + x;
      if (z.hi[c] < z.lo[c]) filled.push_back(c);
      z.add(c, q.z());
    }
    for (const int c : filled)
      if (z.span(c, min_span)) outline.push_back(c);
    return outline;
  };
  // The target's, each with the 8 around it: "within a cell of a target point".
  std::vector<uint8_t> near(size, 0), theirs(size, 0);
  for (const int c : outlineOf(target)) {
    theirs[c] = 1;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) near[c + dy * w + dx] = 1;
  }
  // The object's, and the cells within a cell of them.
  std::vector<uint8_t> mine(size, 0), near_mine(size, 0);
  std::vector<int> cells = outlineOf(object);
  for (const int c : cells) {
    mine[c] = 1;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) near_mine[c + dy * w + dx] = 1;
  }
  std::sort(cells.begin(), cells.end());
  out.cells = cells.size();
  sideEnds(object, target, cells, mine, theirs, w, origin, cell, static_cast<float>(p.reach), at,
           out);
  const auto count = [&](int dx, int dy) {
    std::size_t n = 0;
    const int d = dy * w + dx;
    for (const int c : cells) n += near[c + d];
    return n;
  };
  out.at_rest = count(0, 0);
  // Best: most cells matched, then the nearest to zero, then the first in scan order.
  std::size_t best = out.at_rest;
  int bx = 0, by = 0;
  const auto consider = [&](int dx, int dy) {
    if (std::abs(dx) > reach || std::abs(dy) > reach) return;
    const std::size_t n = count(dx, dy);
    if (n > best || (n == best && dx * dx + dy * dy < bx * bx + by * by))
      best = n, bx = dx, by = dy;
  };
  const int step = std::max(1, p.coarse_step);
  for (int dy = -(reach / step) * step; dy <= reach; dy += step)
    for (int dx = -(reach / step) * step; dx <= reach; dx += step) consider(dx, dy);
  const int cx = bx, cy = by;
  for (int dy = cy - 2; dy <= cy + 2; ++dy)
    for (int dx = cx - 2; dx <= cx + 2; ++dx) consider(dx, dy);
  out.at_shift = best;
  out.shift = Eigen::Vector2f(bx * cell, by * cell);
  if (bx == 0 && by == 0) return out;
  // The cells facing the shift: the outline around each (5 x 5 cells) is a line across it.
  const Eigen::Vector2f u = Eigen::Vector2f(bx, by).normalized();
  const int moved = by * w + bx;
  // A side's trailing end: within the shift (and a cell) of its rearmost cell along the shift.
  const auto along_u = [&](int c) { return (c % w) * u.x() + (c / w) * u.y(); };
  float trailing = std::numeric_limits<float>::infinity();
  for (const int c : cells) trailing = std::min(trailing, along_u(c));
  trailing += std::hypot(static_cast<float>(bx), static_cast<float>(by)) + 1.0f;
  std::vector<uint8_t>& evidence = mine;  // reused: 1 outline, 2 evidence, 3 end evidence
  for (const int c : cells) {
    const int x = c % w, y = c / w;
    double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= w || yy >= h || !mine[static_cast<std::size_t>(yy) * w + xx])
          continue;
        n += 1, sx += dx, sy += dy, sxx += dx * dx, syy += dy * dy, sxy += dx * dy;
      }
    if (n < 3) continue;
    const Spread f = spreadOf(n, sx, sy, sxx, syy, sxy);
    if (!(f.across < 0.2 * f.along)) continue;  // not a line: a roof's fill, a corner, a blob
    // The line's normal: the eigenvector of the smaller eigenvalue.
    Eigen::Vector2d nrm = std::abs(f.b) > 1e-12
                              ? Eigen::Vector2d(f.b, f.across - f.a)
                              : (f.a <= f.d ? Eigen::Vector2d(1, 0) : Eigen::Vector2d(0, 1));
    nrm.normalize();
    if (std::abs(nrm.x() * u.x() + nrm.y() * u.y()) < std::sqrt(0.5)) {
      // A side along the shift: its cells that match only shifted are its ends.
      ++out.along;
      out.along_at_rest += near[c];
      out.along_at_shift += near[c + moved];
      if (!near[c] && near[c + moved] && along_u(c) <= trailing) evidence[c] = 3;
      continue;
    }
    ++out.facing;
    out.facing_at_rest += near[c];
    out.facing_at_shift += near[c + moved];
    if (!near[c] && near[c + moved]) evidence[c] = 2;
  }
  // The target's side of the evidence: its outline cells that a facing evidence cell matches
  // shifted and no cell of the object matches in place (where it stood in the target's alone).
  std::vector<uint8_t>& old_place = theirs;  // reused: 1 outline, 2 old evidence
  for (const int c : cells) {
    if (evidence[c] != 2) continue;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int t = c + moved + dy * w + dx;
        if (old_place[t] == 1 && !near_mine[t]) old_place[t] = 2;
      }
  }
  for (uint32_t i = 0; i < object.size(); ++i) {
    int x, y;
    if (!at(object[i], x, y)) continue;
    if (evidence[y * w + x] == 2) out.evidence.push_back(i);
    if (evidence[y * w + x] == 3) out.end_evidence.push_back(i);
  }
  for (uint32_t i = 0; i < target.size(); ++i) {
    int x, y;
    if (!at(target[i], x, y)) continue;
    if (old_place[y * w + x] == 2) out.old_evidence.push_back(i);
  }
  return out;
}

}  // namespace cleanmap
