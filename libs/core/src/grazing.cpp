// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/grazing.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cleanmap {

// DESIGN §2e, grazing beams. The returns of a scan in columns of azimuth (0.69 degrees; `azimuth`
// per return) and bands of elevation (0.1 degree, a ring or less); a return's lower neighbour is
// the nearest below it in its column. A return lies on a flat surface where its rise from its lower
// neighbour, over their horizontal distance (world frame), is at most flat_slope: the road, a
// sidewalk, a roof. A beam that meets such a surface at a grazing angle runs within `margin` of
// it (across it) for margin / k of horizontal distance, k its slope against the surface's, and
// crosses the voxels that hold the surface there; so does a beam that passes just over one.
// skip_a_ / skip_b_ (metres along the beam) bound the stretch where it marks nothing: for a beam
// ending on a flat surface, from where it comes within margin of it (not before its lower
// neighbour, or that one's where those two are flat too) to its end; for one passing within
// margin over a flat return below it in its column (the nearest it passes so), the stretch within
// margin of that surface's plane, from the return's lower neighbour to graze_reach beyond the
// return (how far the surface goes on is not seen). A return on a descending beam with nothing
// below it in its column is taken to lie on a level surface (unseen below).
void GrazingStretches::compute(const std::vector<PointXYZI>& points, const Eigen::Matrix3f& R,
                               const std::vector<float>& azimuth, double flat_slope,
                               double margin_m, double reach_m, double column_step,
                               double hit_inflate, bool links) {
  constexpr float kElBand = 0.0017f;  // of the elevation's tangent: 0.1 degree near the horizon
  constexpr float kElLow = -1.f;      // tangents -1 to +0.27: -45 to +15 degrees
  const int naz = static_cast<int>(std::ceil(2 * M_PI / kAzBin));
  const std::size_t np = points.size(), ncells = static_cast<std::size_t>(naz) * kElBands;
  // Cells band after band (cell = band * naz + column): a ring's returns in scan order fill
  // neighbouring cells. grid_ holds UINT32_MAX between calls (this call empties the cells it
  // fills); upright_above_ the previous call's marks, cleared from its cells.
  if (grid_.size() != ncells) {
    grid_.assign(ncells, UINT32_MAX);
    upright_above_.assign(ncells, 0);
  } else {
    for (const int c : cell_)
      if (c >= 0) upright_above_[static_cast<std::size_t>(c)] = 0;
  }
  cell_.assign(np, -1);
  band_.resize(np);
  rho_.resize(np);
  zw_.resize(np);
  xw_.resize(np);
  yw_.resize(np);
  int band_lo = kElBands, band_hi = -1;
  for (std::size_t n = 0; n < np; ++n) {
    const auto& q = points[n];
    const float rh = std::sqrt(q.x * q.x + q.y * q.y);
    const Eigen::Vector3f w = R * q.xyz();  // from the sensor, world axes
    rho_[n] = w.head<2>().norm();
    zw_[n] = w.z();
    xw_[n] = w.x();
    yw_[n] = w.y();
    if (!(rh > 0)) continue;
    const int az = std::clamp(static_cast<int>((azimuth[n] + float(M_PI)) / kAzBin), 0, naz - 1);
    const int el = static_cast<int>(std::floor((q.z / rh - kElLow) / kElBand));
    if (el < 0 || el >= kElBands) continue;
    cell_[n] = el * naz + az;
    band_[n] = static_cast<uint16_t>(el);
    band_lo = std::min(band_lo, el);
    band_hi = std::max(band_hi, el);
    grid_[static_cast<std::size_t>(cell_[n])] = static_cast<uint32_t>(n);
  }
  lower_.assign(np, UINT32_MAX);
  slope_.assign(np, std::numeric_limits<float>::quiet_NaN());
  const auto flat = [&](uint32_t n) { return n != UINT32_MAX && !std::isnan(slope_[n]); };
  for (std::size_t n = 0; n < np; ++n) {
    if (cell_[n] < 0) continue;
    const int el = band_[n];
    int c = cell_[n] - naz;
    for (int e = el - 1; e >= std::max(0, el - kMaxDown) && lower_[n] == UINT32_MAX; --e, c -= naz)
      lower_[n] = grid_[static_cast<std::size_t>(c)];
    const uint32_t l = lower_[n];
    if (l == UINT32_MAX) continue;
    slope_[n] = flatRise(n, l, flat_slope);
    if (!std::isnan(slope_[n])) continue;
    // n rises steeply from l: l's cell (every return in it) is the foot of an upright surface
    upright_above_[static_cast<std::size_t>(cell_[l])] = 1;
  }
  // Per cell: the nearest cell at or below it in its column holding a flat return (-1: none).
  // Only the bands from one below the lowest return's to the highest one's are ever read.
  flat_below_.resize(ncells);
  if (band_lo > 0 && band_lo <= band_hi)
    std::fill_n(flat_below_.begin() + std::ptrdiff_t(band_lo - 1) * naz, naz, -1);
  for (int el = band_lo; el <= band_hi; ++el)
    for (int c = el * naz, end = c + naz; c < end; ++c)
      flat_below_[static_cast<std::size_t>(c)] =
          flat(grid_[static_cast<std::size_t>(c)]) ? c
          : el > 0                                 ? flat_below_[static_cast<std::size_t>(c - naz)]
                                                   : -1;
  // A return on a descending beam with nothing returned below it in its column (below).
  const auto unseen = [&](uint32_t n) {
    return n != UINT32_MAX && cell_[n] >= 0 && lower_[n] == UINT32_MAX && zw_[n] < 0;
  };
  skip_a_.assign(np, 0.f);
  skip_b_.assign(np, -1.f);
  const float m = static_cast<float>(margin_m), reach = static_cast<float>(reach_m);
  for (std::size_t n = 0; n < np; ++n) {
    if (cell_[n] < 0 || !(rho_[n] > 0)) continue;
    const float tan_beam = zw_[n] / rho_[n];
    const float along = points[n].xyz().norm() / rho_[n];  // metres along the beam per metre
    const uint32_t l = lower_[n];
    if (flat(static_cast<uint32_t>(n))) {  // it ends on the surface it shares with l
      const float k = slope_[n] - tan_beam;
      if (!(k > 1e-4f)) continue;
      const float from = flat(l)     ? rho_[lower_[l]]
                         : unseen(l) ? std::max(0.f, rho_[l] + m * rho_[l] / zw_[l])
                                     : rho_[l];
      skip_a_[n] = std::max(from, rho_[n] - m / k) * along;
      skip_b_[n] = (rho_[n] + m) * along;
      continue;
    }
    if (unseen(static_cast<uint32_t>(n))) {
      // Nothing returned below it in its column: the lidar's lower beams there met something
      // nearer than its minimum range (a roof or a bonnet passed close) or nothing that echoed,
      // and the surface it lies on is not seen. Taken as level: the beam marks nothing where it
      // runs within margin of the horizontal plane through its return.
      const float k = -tan_beam;
      skip_a_[n] = std::max(0.f, rho_[n] - m / k) * along;
      skip_b_[n] = (rho_[n] + m) * along;
      continue;
    }
    if (reach <= 0) continue;
    // The flat returns below it in its column, nearest first (by the flat-cell links), down to
    // kMaxDown bands below it.
    const int el = band_[n];
    const int stop = std::max(0, el - kMaxDown) * naz + (cell_[n] - el * naz);
    for (int c = el > 0 ? flat_below_[static_cast<std::size_t>(cell_[n] - naz)] : -1; c >= stop;
         c = c >= naz ? flat_below_[static_cast<std::size_t>(c - naz)] : -1) {
      const uint32_t f = grid_[static_cast<std::size_t>(c)];
      if (!(rho_[f] < rho_[n])) continue;
      const float h = tan_beam * rho_[f] - zw_[f];  // the beam's height over the return
      const float k = slope_[f] - tan_beam;
      if (h < 0 || h > m || !(k > 1e-4f)) continue;
      skip_a_[n] = std::max(rho_[lower_[f]], rho_[f] + (h - m) / k) * along;
      skip_b_[n] = std::min(rho_[f] + reach, rho_[f] + (h + m) / k) * along;
      break;
    }
  }
  side_.clear();
  links_.clear();
  if (column_step > 0 && (hit_inflate > 0 || links))
    sides(points, azimuth, naz, m, float(column_step), float(hit_inflate), links,
          float(flat_slope));
  for (const int c : cell_)  // empty the grid for the next call
    if (c >= 0) grid_[static_cast<std::size_t>(c)] = UINT32_MAX;
}

// DESIGN §2e, grazing sides. A return n not on a flat surface, with a return of its band (or
// the next) one or two columns away on each side (L, R) and n on the line through them
// (horizontally, within 0.05 m + 0.5 % of its range): an upright surface, a wall or a car's side,
// met at horizontal incidence alpha (sin alpha from the line's direction and n's azimuth). The
// scan's returns lie about rho step / sin(alpha) apart along it; where that exceeds 2 hit_inflate
// their neighbourhoods (protected from this scan's free space) leave gaps, and n's beam, running
// within `margin` of the surface for margin / sin(alpha) of horizontal range before its end,
// crosses the surface's voxels there. It marks nothing from that far back (not beyond one
// column's gap past its nearer neighbour: the surface is seen from L to R) to its end.
void GrazingStretches::sides(const std::vector<PointXYZI>& points,
                             const std::vector<float>& azimuth, int naz, float m, float step,
                             float hit_inflate, bool links, float flat_slope) {
  const std::size_t np = cell_.size();
  const bool mark = hit_inflate > 0;
  if (mark) side_.assign(np, std::numeric_limits<float>::infinity());
  // The links' columns: the lidar's own where they are finer than the cells' (a dense lidar's
  // neighbouring columns lie in one cell; 1-2 cells away they lie up to 1.4 degrees apart, too
  // far along a side seen at a grazing angle to link), the cells' otherwise.
  const bool fine = links && step < kAzBin;
  fine_links_ = fine;
  const int naz_links = fine ? static_cast<int>(std::ceil(2 * M_PI / step)) : naz;
  if (fine) {
    const std::size_t ncells = static_cast<std::size_t>(naz_links) * kElBands;
    // Grown only: the column step is measured per scan, and a cell past this scan's stays empty.
    if (fine_grid_.size() < ncells) fine_grid_.assign(ncells, UINT32_MAX);
    fine_cell_.assign(np, -1);
    for (std::size_t n = 0; n < np; ++n) {
      if (cell_[n] < 0) continue;
      const int az =
          std::clamp(static_cast<int>((azimuth[n] + float(M_PI)) / step), 0, naz_links - 1);
      fine_cell_[n] = band_[n] * naz_links + az;
      fine_grid_[static_cast<std::size_t>(fine_cell_[n])] = static_cast<uint32_t>(n);
    }
  }
  const std::vector<uint32_t>& link_grid = fine ? fine_grid_ : grid_;
  const std::vector<int>& link_cell = fine ? fine_cell_ : cell_;
  // Per return, in the links' columns: on a flat surface (its rise from the return below it in
  // its column at most flat_slope), and the lowest ring's road (no return below, under the
  // sensor). In the cells' columns a side's return seen at a grazing angle has its lower
  // neighbour columns away, metres farther: a rise that reads as flat.
  if (links) {
    link_kind_.assign(np, 0);
    for (std::size_t n = 0; n < np; ++n) {
      if (cell_[n] < 0) continue;
      uint32_t l = fine ? UINT32_MAX : lower_[n];
      if (fine)
        for (int e = band_[n] - 1, c = fine_cell_[n] - naz_links;
             e >= std::max(0, band_[n] - kMaxDown) && l == UINT32_MAX; --e, c -= naz_links)
          l = fine_grid_[static_cast<std::size_t>(c)];
      const bool flat = fine ? l != UINT32_MAX && !std::isnan(flatRise(n, l, flat_slope))
                             : !std::isnan(slope_[n]);
      link_kind_[n] = (flat ? kLinkFlat : 0) | (l == UINT32_MAX && zw_[n] < 0 ? kLinkRoad : 0);
    }
  }
  // Per return on a line with its neighbours: the line's direction and the two neighbours.
  if (links) {
    dir_x_.assign(np, std::numeric_limits<float>::quiet_NaN());
    dir_y_.resize(np);
    next_a_.assign(np, UINT32_MAX);
    next_b_.assign(np, UINT32_MAX);
  }
  // The nearest return of n's band (or the one above or below it) 1-2 columns to side s.
  const auto beside = [&](const std::vector<uint32_t>& grid, int cell, int columns, std::size_t n,
                          int s) -> uint32_t {
    const int col = cell % columns, el = band_[n];
    for (int k = 1; k <= 2; ++k) {
      const int c = ((col + s * k) % columns + columns) % columns;
      for (const int e : {el, el - 1, el + 1}) {
        if (e < 0 || e >= kElBands) continue;
        const uint32_t q = grid[std::size_t(e) * columns + c];
        if (q != UINT32_MAX) return q;
      }
    }
    return UINT32_MAX;
  };
  // How far off a line a return of it may lie: 0.05 m + 0.5 % of its range.
  const auto tolerance = [&](std::size_t n) { return 0.05f + 0.005f * rho_[n]; };
  // How far x lies from the line from -> to (horizontally; 0 where the two coincide).
  const auto off = [&](uint32_t from, uint32_t to, uint32_t x) {
    const float ux = xw_[to] - xw_[from], uy = yw_[to] - yw_[from];
    const float len = std::sqrt(ux * ux + uy * uy);
    return len > 1e-3f ? std::abs((xw_[x] - xw_[from]) * uy - (yw_[x] - yw_[from]) * ux) / len
                       : 0.f;
  };
  // n on the line through a and b (horizontally), between them: its direction (ux, uy) / len.
  const auto online = [&](std::size_t n, uint32_t a, uint32_t b, float& ux, float& uy, float& len) {
    if (a == UINT32_MAX || b == UINT32_MAX) return false;
    ux = xw_[b] - xw_[a], uy = yw_[b] - yw_[a];
    len = std::sqrt(ux * ux + uy * uy);
    if (!(len > 1e-3f)) return false;
    const float along_ab = ((xw_[n] - xw_[a]) * ux + (yw_[n] - yw_[a]) * uy) / (len * len);
    return along_ab > 0 && along_ab < 1 && off(a, b, uint32_t(n)) <= tolerance(n);
  };
  for (std::size_t n = 0; n < np; ++n) {
    if (cell_[n] < 0 || !(rho_[n] > 0)) continue;
    float ux = 0, uy = 0, len = 0;
    uint32_t a = UINT32_MAX, b = UINT32_MAX;
    bool on_line = false;
    if (links && !(link_kind_[n] & kLinkFlat)) {
      a = beside(link_grid, link_cell[n], naz_links, n, -1);
      b = beside(link_grid, link_cell[n], naz_links, n, +1);
      next_a_[n] = a;
      next_b_[n] = b;
      on_line = online(n, a, b, ux, uy, len);
      if (on_line && !(link_kind_[n] & kLinkRoad)) {
        dir_x_[n] = ux / len;
        dir_y_[n] = uy / len;
      }
    }
    if (!mark || !std::isnan(slope_[n])) continue;
    if (fine || !links) {  // in the cells' columns (else the links' line above is this one)
      a = beside(grid_, cell_[n], naz, n, -1);
      b = beside(grid_, cell_[n], naz, n, +1);
      on_line = online(n, a, b, ux, uy, len);
    }
    if (!on_line) continue;
    const float sin_a = std::abs(ux * yw_[n] - uy * xw_[n]) / (len * rho_[n]);
    if (!(rho_[n] * step > 2 * hit_inflate * sin_a)) continue;  // their neighbourhoods cover it
    const float near = std::min(rho_[a], rho_[b]);
    if (!(near < rho_[n])) continue;  // n is the surface's nearest point: met head-on
    const float from = std::max(rho_[n] - m / std::max(sin_a, 1e-3f), 2 * near - rho_[n]);
    side_[n] = std::max(0.f, from) * (points[n].xyz().norm() / rho_[n]);
  }
  // Links: two neighbours each on a line with its own neighbours, the two lines parallel (four
  // returns in a row): one surface. Three alone are not enough: a walker's face across a wall
  // runs on into the wall's return beside his back.
  constexpr float kParallel = 0.1f;  // sine of the angle between the two lines
  constexpr float kEven = 2.5f;      // a gap over the columns' spacing: one column missing
  const auto spacing2 = [&](uint32_t a, uint32_t b) {
    const float ex = xw_[b] - xw_[a], ey = yw_[b] - yw_[a];
    return ex * ex + ey * ey;
  };
  for (std::size_t n = 0; links && n < np; ++n) {
    if (std::isnan(dir_x_[n])) continue;
    for (const bool after : {false, true}) {
      // q is a return (n has a line only with both neighbours found), a n's other neighbour, r
      // q's beyond it
      const uint32_t q = after ? next_b_[n] : next_a_[n], a = after ? next_a_[n] : next_b_[n];
      const uint32_t r = after ? next_b_[q] : next_a_[q];
      const bool q_line = !std::isnan(dir_x_[q]);
      if (!q_line) {
        // q ends the line (a silhouette): beyond it nothing, or something farther
        if (link_kind_[q]) continue;  // flat, or the lowest ring's road
        if (!(r == UINT32_MAX || rho_[r] > rho_[q] + kMaxLink)) continue;
      } else if (std::abs(dir_x_[n] * dir_y_[q] - dir_y_[n] * dir_x_[q]) > kParallel) {
        continue;
      }
      const float dx = xw_[q] - xw_[n], dy = yw_[q] - yw_[n];
      const float gap2 = dx * dx + dy * dy;
      if (gap2 > kMaxLink * kMaxLink) continue;
      // In one line, not two parallel ones a little apart (a cyclist's side along a parked car's
      // at the curb): the returns beyond each end lie on the line through the other end.
      const float tol = tolerance(n);
      if (off(a, n, q) > tol || (q_line && (off(a, n, r) > tol || off(r, q, a) > tol))) continue;
      // Evenly spaced: one surface's returns in neighbouring columns lie about as far apart as
      // the columns before them (the spacing grows slowly with the grazing angle); two surfaces
      // in one line (a car's face and the next car's, aligned across a gap) jump.
      const float even2 = q_line ? std::max(spacing2(n, a), spacing2(q, r)) : spacing2(n, a);
      if (gap2 > kEven * kEven * even2) continue;
      links_.push_back(static_cast<uint32_t>(n));
      links_.push_back(q);
    }
  }
  if (fine)  // empty the cells for the next call
    for (const int c : fine_cell_)
      if (c >= 0) fine_grid_[static_cast<std::size_t>(c)] = UINT32_MAX;
}

}  // namespace cleanmap
