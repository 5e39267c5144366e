// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/object_consensus.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "cleanmap/core/cell_key.h"
#include "cleanmap/core/cell_map.h"
#include "cleanmap/core/grouped.h"
#include "cleanmap/core/median.h"
#include "cleanmap/core/sensor.h"

namespace cleanmap {

bool vehicleSized(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, double max_length,
                  double max_height) {
  const Eigen::Vector3f ext = hi - lo;
  return ext.head<2>().norm() <= max_length && ext.z() <= max_height;
}

namespace {

// Every field RingReach::operator== compares, for objectConsensus' error on a foreign grouping.
std::string describe(const RingReach& r) {
  return "rings " + std::to_string(r.ring_gap) + " rad apart from (" +
         std::to_string(r.origin.x()) + ", " + std::to_string(r.origin.y()) + "), pool " +
         std::to_string(r.pool) + " m, foot " + std::to_string(r.foot) + " m, max_length " +
         std::to_string(r.max_length) + " m, max_height " + std::to_string(r.max_height) +
         " m, wall_gap " + std::to_string(r.wall_gap) + " m";
}

struct UnionFind {
  std::vector<uint32_t> parent;
  explicit UnionFind(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t find(uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(uint32_t a, uint32_t b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

// Each voxel's 26-neighbours that come after it (forEachNeighbour13), in CSR form, and the one
// above it (UINT32_MAX: none).
struct VoxelLinks {
  std::vector<uint32_t> start, after, up;
};

// Per column of voxels its members' lowest point, and the lowest of its 3 x 3 columns: the
// floor that rule 1's low surfaces and walls measure heights from.
class ColumnFloors {
 public:
  void add(const Eigen::Vector3i& c, float z) {
    bool fresh = false;
    float& low = low_.get(cellKey(c.x(), c.y(), 0), &fresh);
    low = fresh ? z : std::min(low, z);
  }
  float floor(const Eigen::Vector3i& c) {  // after every add()
    bool fresh = false;
    float& f = floor_.get(cellKey(c.x(), c.y(), 0), &fresh);
    if (fresh) {
      f = 1e30f;
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          if (const float* l = low_.find(cellKey(c.x() + dx, c.y() + dy, 0))) f = std::min(f, *l);
    }
    return f;
  }

 private:
  CellMap<float> low_, floor_;
};

// Low surfaces (doc/OBJECTS.md rule 1): a structure (a component larger than an object) joined
// only through low voxels (a sidewalk that is not ground, 0.12 m up, between a parked car, a pole
// and a wall) falls apart into the objects standing on them. A voxel is raised if it holds a
// point at least `foot` above the lowest member of its 3 x 3 column. Raised voxels link among
// themselves; a low voxel right under a raised one is part of it (a car's lowest band); the other
// low voxels link among themselves, and such a cluster that touches one object only is its part.
// `links`: each voxel's 26-neighbours, as groupObjects found them (no voxel table probed again).
void splitOnLowSurfaces(const std::vector<PointXYZI>& points, ObjectComponents& cc,
                        const RingReach& reach, const VoxelLinks& links) {
  const std::size_t nv = cc.voxels.size();
  if (nv == 0) return;
  std::vector<Eigen::Vector3f> lo(nv, Eigen::Vector3f::Constant(1e30f)),
      hi(nv, Eigen::Vector3f::Constant(-1e30f));
  std::vector<float> z_lo(nv, 1e30f), z_hi(nv, -1e30f);  // per voxel
  for (std::size_t i = 0; i < points.size(); ++i) {
    const uint32_t v = cc.point_voxel[i];
    if (v == UINT32_MAX) continue;
    const uint32_t r = cc.root_of[v];
    lo[r] = lo[r].cwiseMin(points[i].xyz());
    hi[r] = hi[r].cwiseMax(points[i].xyz());
    z_lo[v] = std::min(z_lo[v], points[i].z);
    z_hi[v] = std::max(z_hi[v], points[i].z);
  }
  std::vector<uint8_t> structure(nv, 0);
  bool any = false;
  for (uint32_t v = 0; v < nv; ++v) {
    const uint32_t r = cc.root_of[v];
    structure[v] = !vehicleSized(lo[r], hi[r], reach.max_length, reach.max_height);
    any = any || structure[v];
  }
  if (!any) return;
  ColumnFloors columns;
  for (uint32_t v = 0; v < nv; ++v) columns.add(cc.voxels[v], z_lo[v]);
  // 0: raised, 1: low under a raised voxel, 2: other low voxels.
  std::vector<uint8_t> kind(nv, 2);
  const float f = static_cast<float>(reach.foot);
  for (uint32_t v = 0; v < nv; ++v)
    if (structure[v] && z_hi[v] >= columns.floor(cc.voxels[v]) + f) kind[v] = 0;
  UnionFind uf(nv);
  for (uint32_t v = 0; v < nv; ++v) {
    if (!structure[v] || kind[v] == 0) continue;
    const uint32_t n = links.up[v];
    if (n != UINT32_MAX && kind[n] == 0 && cc.root_of[n] == cc.root_of[v]) {
      kind[v] = 1;
      uf.unite(v, n);
    }
  }
  for (uint32_t v = 0; v < nv; ++v) {
    if (!structure[v] || kind[v] == 1) continue;
    for (uint32_t j = links.start[v]; j < links.start[v + 1]; ++j) {
      const uint32_t n = links.after[j];
      if (kind[n] == kind[v] && cc.root_of[n] == cc.root_of[v]) uf.unite(v, n);
    }
  }
  // Each low voxel's 26 neighbours: those after it (links.after) and those before it (the
  // voxels that have it among theirs); the union-find's answers do not depend on the order.
  std::vector<uint32_t> before_start(nv + 1, 0), before(links.after.size());
  for (const uint32_t n : links.after) ++before_start[n + 1];
  for (uint32_t v = 0; v < nv; ++v) before_start[v + 1] += before_start[v];
  {
    std::vector<uint32_t> at(before_start.begin(), before_start.end() - 1);
    for (uint32_t v = 0; v < nv; ++v)
      for (uint32_t j = links.start[v]; j < links.start[v + 1]; ++j)
        before[at[links.after[j]]++] = v;
  }
  constexpr uint32_t kNone = UINT32_MAX, kMany = UINT32_MAX - 1;
  std::vector<uint32_t> touches(nv, kNone);  // per low cluster: the one object it touches
  for (uint32_t v = 0; v < nv; ++v) {
    if (!structure[v] || kind[v] != 2) continue;
    uint32_t& t = touches[uf.find(v)];
    const auto touch = [&](uint32_t n) {
      if (kind[n] == 2 || cc.root_of[n] != cc.root_of[v]) return;
      const uint32_t obj = uf.find(n);
      t = t == kNone || t == obj ? obj : kMany;
    };
    for (uint32_t j = links.start[v]; j < links.start[v + 1]; ++j) touch(links.after[j]);
    for (uint32_t j = before_start[v]; j < before_start[v + 1]; ++j) touch(before[j]);
  }
  for (uint32_t v = 0; v < nv; ++v)
    if (structure[v] && kind[v] == 2 && uf.find(v) == v && touches[v] != kNone &&
        touches[v] != kMany)
      uf.unite(v, touches[v]);
  cc.piece.assign(nv, 0);
  for (uint32_t v = 0; v < nv; ++v)
    if (structure[v]) {
      cc.root_of[v] = uf.find(v);
      cc.piece[cc.root_of[v]] = 1;
    }
}

// Beside a wall (doc/OBJECTS.md rule 1): a body standing against an upright plane (a walker
// with his back 5 cm from a wall) shares voxels with it at any voxel size, and the structure
// takes him whole, out of the object rules. A structure's raised returns (reach.foot or more
// over the lowest of their voxel's 3 x 3 columns: not a sidewalk along it) lie on one upright
// plane where at least kWallShare of them lie within reach.wall_gap of a line fitted to their
// voxels' columns (its offset then their median; half the columns must lie within wall_gap and
// half a voxel's diagonal of it before the returns are asked). Its raised voxels most of whose
// returns lie more than wall_gap in front of the plane (on the sensor's side, reach.origin), with
// the low voxels right under them that do too, join among themselves; such a group of a vehicle's
// size that reaches down to the structure's floor (within reach.foot, or 1.5 ring steps at its
// range where more) is a component of its own, a piece (rule 2 may turn it moving, not static).
// The rest stays one structure as it was: recesses and what lies behind the plane never part.
// A component of a vehicle's size over kPlaneLength long is asked too ("A stretch of a wall");
// what parts from it is a component like any other.
void splitFromWalls(const std::vector<PointXYZI>& points, ObjectComponents& cc,
                    const RingReach& reach, bool after_low_surfaces) {
  constexpr double kWallShare = 0.75;
  constexpr float kPlaneLength = 3.0f;  // m: see `structure`
  const std::size_t nv = cc.voxels.size();
  if (nv == 0 || reach.wall_gap <= 0) return;
  // The components asked: every structure and piece of one (after the low surfaces' split, the
  // roots it marked, whether it fell apart or not; without it, the components over a vehicle's
  // size), and those of a vehicle's size longer than kPlaneLength: a wall's stretch that a
  // walker's shadow cut under max_length (`pedestrian_wall` seen by an OS1-64, scans 0-16) is
  // one. A convex body (a vehicle) has nothing in front of its own faces, and kPlaneLength is
  // over a vehicle's width: a truck seen from behind, its bumper in front of its rear face, is
  // never asked (kitti_highway scan 25 at 2 m). Only a structure's rest stays a piece
  // (`marked`), and what parts from a vehicle-sized component is a component like any other.
  std::vector<uint8_t> structure(nv, 0), marked(nv, 0), vehicle_sized(nv, 0);
  bool any = false;
  {
    std::vector<Eigen::Vector3f> lo(nv, Eigen::Vector3f::Constant(1e30f)),
        hi(nv, Eigen::Vector3f::Constant(-1e30f));
    for (std::size_t i = 0; i < points.size(); ++i) {
      const uint32_t v = cc.point_voxel[i];
      if (v == UINT32_MAX) continue;
      lo[cc.root_of[v]] = lo[cc.root_of[v]].cwiseMin(points[i].xyz());
      hi[cc.root_of[v]] = hi[cc.root_of[v]].cwiseMax(points[i].xyz());
    }
    for (uint32_t r = 0; r < nv; ++r) {
      if (cc.root_of[r] != r || !(lo[r].x() <= hi[r].x())) continue;
      const bool vehicle = vehicleSized(lo[r], hi[r], reach.max_length, reach.max_height);
      marked[r] = after_low_surfaces && r < cc.piece.size() && cc.piece[r];
      vehicle_sized[r] = vehicle && !marked[r];
      structure[r] = marked[r] || (!after_low_surfaces && !vehicle) ||
                     (vehicle_sized[r] && (hi[r] - lo[r]).head<2>().norm() >= kPlaneLength);
      any = any || structure[r];
    }
  }
  if (!any) return;
  // The structures' voxels and points, by root; their columns' lowest returns.
  std::vector<uint32_t> vox_root, vox_index, pt_root, pt_index;
  for (uint32_t v = 0; v < nv; ++v)
    if (structure[cc.root_of[v]]) {
      vox_root.push_back(cc.root_of[v]);
      vox_index.push_back(v);
    }
  std::vector<float> z_lo(nv, 1e30f), z_hi(nv, -1e30f);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const uint32_t v = cc.point_voxel[i];
    if (v == UINT32_MAX || !structure[cc.root_of[v]]) continue;
    pt_root.push_back(cc.root_of[v]);
    pt_index.push_back(static_cast<uint32_t>(i));
    z_lo[v] = std::min(z_lo[v], points[i].z);
    z_hi[v] = std::max(z_hi[v], points[i].z);
  }
  Grouped vox_of, pts_of;
  vox_of.assign(vox_root, nv, &vox_index);
  pts_of.assign(pt_root, nv, &pt_index);
  ColumnFloors columns;
  for (const uint32_t v : vox_index) columns.add(cc.voxels[v], z_lo[v]);
  const float foot = static_cast<float>(reach.foot);
  std::vector<float> floor(nv, 1e30f);  // per structure voxel: the lowest of its 3 x 3 columns
  for (const uint32_t v : vox_index) floor[v] = columns.floor(cc.voxels[v]);
  const auto raised = [&](std::size_t i) { return points[i].z >= floor[cc.point_voxel[i]] + foot; };
  // A group reaches its floor within foot, or 1.5 ring steps at its range where more (Overhead):
  // a VLP-16's lowest ring on a walker 15 m off lands 0.5 m over the sidewalk.
  const auto floorGap = [&](const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
    const Eigen::Vector2d at = 0.5 * (lo + hi).head<2>().cast<double>();
    return static_cast<float>(std::max(reach.foot, 1.5 * reach.stepAt(at)));
  };
  const double side = cc.side;
  const float gap = static_cast<float>(reach.wall_gap);
  std::vector<uint8_t> off(nv, 0);
  std::vector<uint32_t> in_voxel(nv, 0), off_in_voxel(nv, 0), new_root(nv, UINT32_MAX);
  std::vector<float> offset;
  std::vector<double> across_of;  // per return of the structure (ps), its offset across the line
  UnionFind uf(nv);               // the groups in front of a plane, and their boxes and floors
  std::vector<Eigen::Vector3f> glo(nv), ghi(nv);
  std::vector<float> gfloor(nv);
  std::vector<uint8_t> narrow(nv, 0);  // a sparse lidar's slice in front of the plane
  std::vector<Eigen::Vector2f> galong(nv, Eigen::Vector2f(1e30f, -1e30f));  // along the plane
  std::vector<std::pair<uint32_t, uint32_t>> handed;  // (return, voxel of the body it joins)
  bool split_any = false;
  for (uint32_t r = 0; r < nv; ++r) {
    if (!structure[r]) continue;
    const auto vs = vox_of[r];
    const auto ps = pts_of[r];
    // The line: the main axis of the raised voxels' columns, then of those within a voxel of
    // the line through their median offset.
    Eigen::Vector2d mean = Eigen::Vector2d::Zero(), n = Eigen::Vector2d::Zero();
    const auto centre = [&](uint32_t v) {
      return Eigen::Vector2d((cc.voxels[v].head<2>().cast<double>().array() + 0.5) * side);
    };
    const auto fit = [&](auto&& keep) {
      Eigen::Vector2d m = Eigen::Vector2d::Zero();
      Eigen::Matrix2d s = Eigen::Matrix2d::Zero();
      std::size_t k = 0;
      for (const uint32_t v : vs) {
        const Eigen::Vector2d c = centre(v);
        if (z_hi[v] < floor[v] + foot || !keep(c)) continue;
        m += c;
        s += c * c.transpose();
        ++k;
      }
      if (k < 2) return false;
      m /= static_cast<double>(k);
      s = s / static_cast<double>(k) - m * m.transpose();
      const double angle = 0.5 * std::atan2(2 * s(0, 1), s(0, 0) - s(1, 1));  // the main axis
      mean = m;
      n = Eigen::Vector2d(-std::sin(angle), std::cos(angle));
      return true;
    };
    const auto across = [&](std::size_t i) {
      return n.dot(Eigen::Vector2d(points[i].x, points[i].y) - mean);
    };
    // (`offset` is never empty where its median is asked: a raised voxel holds a raised return)
    const auto returns_median = [&] {  // the raised returns' offsets (across_of, filled first)
      offset.clear();
      for (std::size_t k = 0; k < ps.size(); ++k)
        if (raised(ps[k])) offset.push_back(static_cast<float>(across_of[k]));
      return static_cast<double>(median(offset));
    };
    const auto voxels_median = [&] {  // the raised voxels' columns'
      offset.clear();
      for (const uint32_t v : vs)
        if (z_hi[v] >= floor[v] + foot)
          offset.push_back(static_cast<float>(n.dot(centre(v) - mean)));
      return static_cast<double>(median(offset));
    };
    if (!fit([](const Eigen::Vector2d&) { return true; })) continue;
    double c = voxels_median();
    const Eigen::Vector2d m0 = mean, n0 = n;
    if (!fit([&](const Eigen::Vector2d& x) { return std::abs(n0.dot(x - m0) - c) <= side; }))
      continue;
    // Before the returns are asked: a plane holding 3 in 4 of them holds most raised voxels
    // within wall_gap and half a voxel's diagonal (a structure of other shapes ends here).
    c = voxels_median();
    std::size_t near = 0;
    for (const float o : offset) near += std::abs(o - c) <= reach.wall_gap + side * M_SQRT1_2;
    if (2 * near < offset.size()) continue;
    across_of.resize(ps.size());  // each return's offset from the final line, kept once
    for (std::size_t k = 0; k < ps.size(); ++k) across_of[k] = across(ps[k]);
    c = returns_median();
    const double sensor = n.dot(reach.origin - mean) - c;  // the sensor's side of the plane
    if (std::abs(sensor) <= reach.wall_gap) continue;
    const float sign = sensor > 0 ? 1.f : -1.f;
    std::size_t on_plane = 0, raised_n = 0;
    float plane_lo = 1e30f, plane_hi = -1e30f;  // the heights of its returns on the plane
    for (std::size_t k = 0; k < ps.size(); ++k) {
      const uint32_t i = ps[k];
      const float d = sign * static_cast<float>(across_of[k] - c);
      if (std::abs(d) <= gap) {
        plane_lo = std::min(plane_lo, points[i].z);
        plane_hi = std::max(plane_hi, points[i].z);
      }
      if (raised(i)) {
        ++raised_n;
        on_plane += std::abs(d) <= gap;
      }
      ++in_voxel[cc.point_voxel[i]];
      off_in_voxel[cc.point_voxel[i]] += d > gap;
    }
    if (static_cast<double>(on_plane) < kWallShare * static_cast<double>(raised_n)) continue;
    bool has_off = false;
    for (const uint32_t v : vs) {
      off[v] = 2 * off_in_voxel[v] > in_voxel[v] && z_hi[v] >= floor[v] + foot;
      has_off = has_off || off[v];
    }
    if (!has_off) continue;
    for (const uint32_t v : vs) {
      if (off[v] || 2 * off_in_voxel[v] <= in_voxel[v]) continue;
      const Eigen::Vector3i& x = cc.voxels[v];
      const uint32_t* up = cc.voxel_of.find(cellKey(x.x(), x.y(), x.z() + 1));
      bool under = up && off[*up] == 1 && cc.root_of[*up] == r;  // low, under a raised one
      // Or a ring step under it (doc/OBJECTS.md rule 1, "His lowest ring"): a sparse lidar's
      // lowest ring on the wall is its floor, and a walker's beside it is level with it.
      if (!under && reach.active())
        forEachRingAbove(cc, v,
                         [&](uint32_t w) { under = under || (off[w] == 1 && cc.root_of[w] == r); });
      if (under) off[v] = 2;
    }
    // The groups in front of the plane.
    for (const uint32_t v : vs) uf.parent[v] = v;  // (only this structure's voxels take part)
    const auto boxes = [&] {                       // each group's box of returns and its floor
      for (const uint32_t v : vs) {
        glo[v] = Eigen::Vector3f::Constant(1e30f);
        ghi[v] = Eigen::Vector3f::Constant(-1e30f);
        gfloor[v] = 1e30f;
      }
      for (const uint32_t i : ps) {
        const uint32_t v = cc.point_voxel[i];
        if (!off[v]) continue;
        const uint32_t g = uf.find(v);
        glo[g] = glo[g].cwiseMin(points[i].xyz());
        ghi[g] = ghi[g].cwiseMax(points[i].xyz());
        gfloor[g] = std::min(gfloor[g], floor[v]);
      }
    };
    for (const uint32_t v : vs) {
      if (!off[v]) continue;
      forEachLinked(cc, v, [&](uint32_t w) {
        if (off[w] && cc.root_of[w] == r) uf.unite(v, w);
      });
    }
    // A sparse lidar's slices in front of the plane join across rings as rule 1's slices do
    // (RingReach): those at most reach.pool across (their returns' horizontal diagonal), in a
    // 3 x 3 column within kRingReach ring steps. A walker by a wall seen by an HDL-32E 16-20 m
    // off is a slice a ring, 0.46 m apart: only his lowest reached the floor and parted, the
    // rest stayed the wall's (`pedestrian_wall`, scans 0-6: none of him found).
    if (reach.active()) {
      boxes();
      for (const uint32_t v : vs)
        narrow[v] = off[v] && (ghi[uf.find(v)] - glo[uf.find(v)]).head<2>().norm() <= reach.pool;
      for (const uint32_t v : vs) {
        if (!narrow[v]) continue;
        forEachRingAbove(cc, v, [&](uint32_t w) {
          if (narrow[w] && cc.root_of[w] == r) uf.unite(v, w);
        });
      }
    }
    boxes();
    bool parted = false;
    for (const uint32_t v : vs) {
      if (!off[v]) continue;
      const uint32_t g = uf.find(v);
      // In a component of a vehicle's size, the plane must stand behind the group over its
      // heights (within foot): a wall, not a car's roof seen as a line from above (the follower
      // of `following_car` 1.8 m behind the sensor: its front's corner parted, 40 returns lost).
      // And the group must stand at least half as high as the plane, from its floor up: a body
      // before a wall, not a parked car's wheels or bumper in front of its side
      // (kitti_residential: 0.15-0.6 m high under sides 2 m high, dozens a run). From its floor:
      // a sparse lidar's ring at a walker's feet lies in the foot band, outside the group.
      const bool behind =
          !vehicle_sized[r] ||
          (plane_lo <= glo[g].z() + foot && plane_hi >= ghi[g].z() - foot &&
           2 * (ghi[g].z() - std::min(glo[g].z(), gfloor[g])) >= plane_hi - plane_lo);
      if (behind && vehicleSized(glo[g], ghi[g], reach.max_length, reach.max_height) &&
          glo[g].z() <= gfloor[g] + floorGap(glo[g], ghi[g])) {
        new_root[v] = g;  // the group's smallest voxel (UnionFind keeps the smaller root)
        parted = true;
      }
    }
    if (!parted) continue;
    split_any = true;
    // A parted body's band within wall_gap of the plane (a walker's sides by his back) lies in
    // the wall's voxels. Its raised returns further in front than the wall's own scatter (3
    // sigma, from the median |offset| of the raised returns within wall_gap), in a voxel beside
    // one of the body's, within wall_gap of the body's extent along the plane (his side is its
    // end) and within its heights, go to that voxel (the nearest such).
    offset.clear();
    for (std::size_t k = 0; k < ps.size(); ++k)
      if (raised(ps[k]) && std::abs(across_of[k] - c) <= reach.wall_gap)
        offset.push_back(static_cast<float>(std::abs(across_of[k] - c)));
    const double scatter =
        offset.empty() ? 0.0 : 3 * kMadToSigma * static_cast<double>(median(offset));
    const Eigen::Vector2d along(n.y(), -n.x());
    const auto alongOf = [&](std::size_t i) {
      return along.dot(Eigen::Vector2d(points[i].x, points[i].y) - mean);
    };
    for (const uint32_t i : ps) {  // the bodies' extents along the plane (raised returns)
      const uint32_t v = cc.point_voxel[i];
      if (new_root[v] == UINT32_MAX || !raised(i)) continue;
      const float a = static_cast<float>(alongOf(i));
      galong[new_root[v]] = {std::min(galong[new_root[v]].x(), a),
                             std::max(galong[new_root[v]].y(), a)};
    }
    handed.clear();
    for (std::size_t k = 0; k < ps.size(); ++k) {
      const uint32_t i = ps[k];
      const uint32_t v = cc.point_voxel[i];
      if (new_root[v] != UINT32_MAX || !raised(i)) continue;
      const double d = sign * (across_of[k] - c);
      if (!(d > scatter) || d > reach.wall_gap) continue;
      const Eigen::Vector3i& x = cc.voxels[v];
      const float a = static_cast<float>(alongOf(i));
      uint32_t best = UINT32_MAX;
      float best_d2 = 1e30f;
      forEachNeighbour27([&](int dx, int dy, int dz) {
        const uint32_t* w = cc.voxel_of.find(cellKey(x.x() + dx, x.y() + dy, x.z() + dz));
        if (!w || cc.root_of[*w] != r || new_root[*w] == UINT32_MAX) return;
        const uint32_t g = new_root[*w];
        if (a < galong[g].x() - gap || a > galong[g].y() + gap || points[i].z < glo[g].z() ||
            points[i].z > ghi[g].z())
          return;
        const float d2 = ((cc.voxels[*w].cast<float>().array() + 0.5f) * static_cast<float>(side) -
                          points[i].xyz().array())
                             .matrix()
                             .squaredNorm();
        if (d2 < best_d2 || (d2 == best_d2 && *w < best)) best = *w, best_d2 = d2;
      });
      if (best != UINT32_MAX) handed.emplace_back(i, best);
    }
    for (const auto& [i, w] : handed) cc.point_voxel[i] = w;
  }
  if (!split_any) return;
  // The rest of each structure is rooted at its smallest voxel left.
  std::vector<uint32_t> rest(nv, UINT32_MAX);
  for (uint32_t v = 0; v < nv; ++v)
    if (new_root[v] == UINT32_MAX && structure[cc.root_of[v]] && rest[cc.root_of[v]] == UINT32_MAX)
      rest[cc.root_of[v]] = v;
  // The parted groups are pieces; the rest is one as its structure was (the low surfaces' split
  // marked every structure it saw).
  if (cc.piece.empty()) cc.piece.assign(nv, 0);
  for (uint32_t v = 0; v < nv; ++v) {
    const uint32_t r = cc.root_of[v];
    if (!structure[r]) continue;
    const bool parted = new_root[v] != UINT32_MAX;
    cc.root_of[v] = parted ? new_root[v] : rest[r];
    cc.piece[cc.root_of[v]] = (parted && !vehicle_sized[r]) || marked[r];
  }
}

}  // namespace

void groupObjects(const std::vector<PointXYZI>& points, const std::vector<uint8_t>& member,
                  double side, ObjectComponents& cc, const RingReach& reach,
                  const std::vector<uint32_t>* column_links, bool cap_links) {
  cc.side = side;
  cc.reach = reach;
  cc.voxel_of.clear();
  cc.voxels.clear();
  const float inv = static_cast<float>(1.0 / side);
  cc.voxel_of.reserve(static_cast<std::size_t>(
      std::count_if(member.begin(), member.end(), [](uint8_t m) { return m != 0; })));
  cc.point_voxel.assign(points.size(), UINT32_MAX);
  // Neighbouring returns of a ring mostly share a voxel: the previous member's is checked before
  // the table (issue #16: a probe per point missed the cache).
  uint64_t last_key = CellMap<uint32_t>::kEmpty;
  uint32_t last_voxel = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!member[i]) continue;
    const Eigen::Vector3i c(static_cast<int>(floorToCell(points[i].x, inv)),
                            static_cast<int>(floorToCell(points[i].y, inv)),
                            static_cast<int>(floorToCell(points[i].z, inv)));
    const uint64_t key = cellKey(c.x(), c.y(), c.z());
    if (key != last_key) {
      bool fresh = false;
      uint32_t& v = cc.voxel_of.get(key, &fresh);
      if (fresh) {
        v = static_cast<uint32_t>(cc.voxels.size());
        cc.voxels.push_back(c);
      }
      last_key = key;
      last_voxel = v;
    }
    cc.point_voxel[i] = last_voxel;
  }
  // One bit per hashed voxel key (issue #16): most of a voxel's forward neighbours are empty, and
  // a clear bit in 32 KiB (cache resident) rejects one before a probe of the voxel table, which
  // misses the cache. A set bit may be another voxel's: the table then answers.
  constexpr int kOccupancyBits = 18;
  const auto bit = [](uint64_t key) {
    return static_cast<std::size_t>((key * 0xD6E8FEB86659FD93ull) >> (64 - kOccupancyBits));
  };
  std::vector<uint64_t> occupied((std::size_t(1) << kOccupancyBits) / 64, 0);
  for (const Eigen::Vector3i& c : cc.voxels) {
    const std::size_t b = bit(cellKey(c.x(), c.y(), c.z()));
    occupied[b >> 6] |= uint64_t(1) << (b & 63);
  }
  // Each pair of neighbours met once (the root is the smallest voxel whatever the order of the
  // unions). The links found are kept for the low surfaces' split, which asks the same.
  const bool split = reach.foot > 0;
  VoxelLinks links;
  if (split) {
    links.start.resize(cc.voxels.size() + 1);
    links.up.assign(cc.voxels.size(), UINT32_MAX);
  }
  // Coarse columns: the voxel pairs of member returns of one surface in neighbouring columns
  // (GrazingStretches::links), each once, smaller voxel first.
  std::vector<std::pair<uint32_t, uint32_t>> across;
  if (column_links)
    for (std::size_t k = 0; k + 1 < column_links->size(); k += 2) {
      const uint32_t a = (*column_links)[k], b = (*column_links)[k + 1];
      if (a >= points.size() || b >= points.size()) continue;
      const uint32_t va = cc.point_voxel[a], vb = cc.point_voxel[b];
      if (va == UINT32_MAX || vb == UINT32_MAX || va == vb) continue;
      across.emplace_back(std::min(va, vb), std::max(va, vb));
    }
  std::sort(across.begin(), across.end());
  across.erase(std::unique(across.begin(), across.end()), across.end());
  // Kept (CSR) so that the groups inside a component join as the component did (forEachLinked).
  cc.across_start.clear();
  cc.across.clear();
  if (!across.empty()) {
    cc.across_start.assign(cc.voxels.size() + 1, 0);
    for (const auto& [a, b] : across) {
      ++cc.across_start[a + 1];
      cc.across.push_back(b);
    }
    for (std::size_t v = 0; v < cc.voxels.size(); ++v) cc.across_start[v + 1] += cc.across_start[v];
  }
  UnionFind uf(cc.voxels.size());
  for (uint32_t v = 0; v < cc.voxels.size(); ++v) {
    const Eigen::Vector3i& c = cc.voxels[v];
    if (split) links.start[v] = static_cast<uint32_t>(links.after.size());
    forEachNeighbour13([&](int dx, int dy, int dz) {
      const uint64_t key = cellKey(c.x() + dx, c.y() + dy, c.z() + dz);
      const std::size_t b = bit(key);
      if (!((occupied[b >> 6] >> (b & 63)) & 1u)) return;
      const uint32_t* n = cc.voxel_of.find(key);
      if (!n) return;
      uf.unite(v, *n);
      if (!split) return;
      links.after.push_back(*n);
      if (dx == 0 && dy == 0) links.up[v] = *n;  // (0, 0, 1): the only forward offset in-column
    });
  }
  if (split) links.start[cc.voxels.size()] = static_cast<uint32_t>(links.after.size());
  // The column links join what the voxels joined, smaller voxel first; capped, never into more
  // than a vehicle's size (reach.max_length / max_height; doc/OBJECTS.md rule 1, "Dense
  // columns"): at a dense lidar they are there to join a car's side met at a grazing angle to
  // its car (its voxels join its walls elsewhere), and a hedge they carried past 25 m fell into
  // pieces (rule 1, "Low surfaces"), whose alarms no rule turns static. At coarse columns they
  // make the walls themselves, and capped they left pedestrian_wall's far walker a wall's piece
  // of a vehicle's size to move (precision 0.976 -> 0.760 at 512 columns).
  if (!cc.across.empty()) {
    const bool cap = cap_links && reach.max_length > 0;
    std::vector<Eigen::Vector3i> lo, hi;  // per root, in voxels
    if (cap) {
      lo.assign(cc.voxels.size(), Eigen::Vector3i::Constant(INT32_MAX));
      hi.assign(cc.voxels.size(), Eigen::Vector3i::Constant(INT32_MIN));
      for (uint32_t v = 0; v < cc.voxels.size(); ++v) {
        const uint32_t r = uf.find(v);
        lo[r] = lo[r].cwiseMin(cc.voxels[v]);
        hi[r] = hi[r].cwiseMax(cc.voxels[v]);
      }
    }
    // Capped, the links kept replace cc.across (CSR); uncapped, all are kept as they are.
    std::vector<uint32_t> start, kept;
    if (cap) start.assign(cc.voxels.size() + 1, 0);
    for (uint32_t v = 0; v < cc.voxels.size(); ++v) {
      for (uint32_t j = cc.across_start[v]; j < cc.across_start[v + 1]; ++j) {
        const uint32_t n = cc.across[j], ra = uf.find(v), rb = uf.find(n);
        if (cap && ra != rb) {
          const Eigen::Vector3i l = lo[ra].cwiseMin(lo[rb]), h = hi[ra].cwiseMax(hi[rb]);
          const Eigen::Vector3d ext = (h - l + Eigen::Vector3i::Ones()).cast<double>() * side;
          if (ext.head<2>().norm() > reach.max_length || ext.z() > reach.max_height) continue;
          uf.unite(v, n);
          lo[uf.find(v)] = l;
          hi[uf.find(v)] = h;
        } else {
          uf.unite(v, n);
        }
        if (cap) kept.push_back(n);
      }
      if (cap) start[v + 1] = static_cast<uint32_t>(kept.size());
    }
    if (cap) {
      cc.across_start.swap(start);
      cc.across.swap(kept);
      if (cc.across.empty()) cc.across_start.clear();
    }
    if (split && !cc.across.empty()) {  // the links kept, first in each voxel's list
      std::vector<uint32_t> after;
      after.reserve(links.after.size() + cc.across.size());
      for (uint32_t v = 0; v < cc.voxels.size(); ++v) {
        const uint32_t from = static_cast<uint32_t>(after.size());
        after.insert(after.end(), cc.across.begin() + cc.across_start[v],
                     cc.across.begin() + cc.across_start[v + 1]);
        after.insert(after.end(), links.after.begin() + links.start[v],
                     links.after.begin() + links.start[v + 1]);
        links.start[v] = from;
      }
      links.start[cc.voxels.size()] = static_cast<uint32_t>(after.size());
      links.after.swap(after);
    }
  }
  // A sparse lidar's slices (the components so far) at most reach.pool across (their returns'
  // horizontal diagonal: the voxels' span reads a 0.6 m walker's slice 0.9-1.2 m across as the
  // grid falls) join those of their column across rings (RingReach).
  cc.pooled.clear();
  if (reach.active() && !cc.voxels.empty()) {
    std::vector<Eigen::Vector2f> lo(cc.voxels.size(), Eigen::Vector2f::Constant(1e30f)),
        hi(cc.voxels.size(), Eigen::Vector2f::Constant(-1e30f));
    std::vector<uint32_t> slice(cc.voxels.size());
    for (uint32_t v = 0; v < cc.voxels.size(); ++v) slice[v] = uf.find(v);
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (cc.point_voxel[i] == UINT32_MAX) continue;
      const uint32_t s = slice[cc.point_voxel[i]];
      const Eigen::Vector2f q(points[i].x, points[i].y);
      lo[s] = lo[s].cwiseMin(q);
      hi[s] = hi[s].cwiseMax(q);
    }
    cc.pooled.resize(cc.voxels.size());
    for (uint32_t v = 0; v < cc.voxels.size(); ++v)
      cc.pooled[v] = (hi[slice[v]] - lo[slice[v]]).norm() <= reach.pool;
    for (uint32_t v = 0; v < cc.voxels.size(); ++v)
      forEachAcrossRings(cc, v, [&](uint32_t n) { uf.unite(v, n); });
  }
  cc.root_of.resize(cc.voxels.size());  // each voxel's component, found once
  for (uint32_t v = 0; v < cc.voxels.size(); ++v) cc.root_of[v] = uf.find(v);
  cc.piece.clear();
  if (split) splitOnLowSurfaces(points, cc, reach, links);
  splitFromWalls(points, cc, reach, split);
}

std::vector<float> componentWidths(const ObjectComponents& cc, double foot) {
  const std::size_t nv = cc.voxels.size();
  std::vector<int> z_lo(nv, std::numeric_limits<int>::max());
  for (std::size_t v = 0; v < nv; ++v)
    z_lo[cc.root_of[v]] = std::min(z_lo[cc.root_of[v]], cc.voxels[v].z());
  // The layers from ceil(foot / side) above the lowest up: a sidewalk a car touches is not its
  // width, nor is a car's its sills' (both are rule 2's foot).
  const int up = foot > 0 ? static_cast<int>(std::ceil(foot / cc.side - 1e-9)) : 0;
  struct Moments {
    double n = 0, x = 0, y = 0, xx = 0, xy = 0, yy = 0;
    void add(double a, double b) {
      n += 1;
      x += a;
      y += b;
      xx += a * a;
      xy += a * b;
      yy += b * b;
    }
  };
  std::vector<Moments> raised(nv), all(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    const uint32_t r = cc.root_of[v];
    const Eigen::Vector3i& c = cc.voxels[v];
    all[r].add(c.x(), c.y());
    if (c.z() >= z_lo[r] + up) raised[r].add(c.x(), c.y());
  }
  std::vector<float> width(nv, 0.0f);
  for (std::size_t v = 0; v < nv; ++v) {
    if (cc.root_of[v] != v) continue;
    const Moments& m = raised[v].n > 0 ? raised[v] : all[v];
    const double mx = m.x / m.n, my = m.y / m.n;
    const double a = m.xx / m.n - mx * mx, b = m.xy / m.n - mx * my, d = m.yy / m.n - my * my;
    const double lambda_min = 0.5 * (a + d - std::sqrt((a - d) * (a - d) + 4.0 * b * b));
    width[v] = static_cast<float>(std::sqrt(12.0 * std::max(0.0, lambda_min)) * cc.side);
  }
  return width;
}

bool Overhead::over(const Eigen::Vector3f& x, uint32_t object, float base, float gap) const {
  const int from = std::max(0, static_cast<int>(std::floor((x.z() + kRise - base) / kCell)));
  const int to = std::min(31, static_cast<int>(std::floor((x.z() + gap - base) / kCell)));
  if (from > to) return false;
  const uint32_t want = (to == 31 ? ~0u : (2u << to) - 1u) & ~((1u << from) - 1u);
  const int r = reach_;
  for (int dx = -r; dx <= r; ++dx)
    for (int dy = -r; dy <= r; ++dy) {
      const int ax = std::max(0, std::abs(dx) - 1), ay = std::max(0, std::abs(dy) - 1);
      if (ax * ax + ay * ay >= r * r) continue;  // no part of that cell within reach
      const uint32_t* s = slices_.find(key(x, object, dx, dy));
      if (s && (*s & want)) return true;
    }
  return false;
}

void Foot::add(const Eigen::Vector3f& x, uint32_t object, float base, bool raises) {
  overhead_.add(x, object, base);
  if (!low(x.z(), base)) {
    if (raises) raised_.insert(column(x, object, 0, 0));
  } else if (levels_ && x.z() < stand_top_ && band_.insert(column(x, kAround, 0, 0))) {
    for (int dx = -1; dx <= 1; ++dx)  // only where level() may ask
      for (int dy = -1; dy <= 1; ++dy) near_band_.insert(column(x, kAround, dx, dy));
  }
}
void Foot::addAround(const Eigen::Vector3f& x) {
  const uint64_t key = column(x, kAround, 0, 0);
  if (near_band_.contains(key)) around_.emplace_back(key, x.z());
}
void Foot::settle() {
  std::sort(around_.begin(), around_.end());
}
// doc/OBJECTS.md rule 2, "Level with the surface around it": in each column of x's 3 x 3 the
// lowest sample around the objects within the foot band's height of the object's lowest
// (`base`): a floor's, or a wall's foot on it. At least kLevelColumns of them, most within
// kLevelBand of their median, and x within kLevelBand of it. Only where Overhead applies
// (foot_reach > 0, below stand_top).
bool Foot::level(const Eigen::Vector3f& x, float base) const {
  if (!levels_ || around_.empty() || !(x.z() < stand_top_)) return false;
  float lowest[9];
  int n = 0;
  for (int dx = -1; dx <= 1; ++dx)
    for (int dy = -1; dy <= 1; ++dy) {
      const uint64_t key = column(x, kAround, dx, dy);
      auto it = std::lower_bound(around_.begin(), around_.end(),
                                 std::make_pair(key, -std::numeric_limits<float>::infinity()));
      for (; it != around_.end() && it->first == key; ++it)  // heights ascending
        if (std::abs(it->second - base) < foot_) {
          lowest[n++] = it->second;
          break;
        }
    }
  if (n < static_cast<int>(kLevelColumns)) return false;
  std::nth_element(lowest, lowest + n / 2, lowest + n);
  const float m = lowest[n / 2];
  const auto near =
      std::count_if(lowest, lowest + n, [&](float z) { return std::abs(z - m) <= kLevelBand; });
  return 2 * near > n && near >= static_cast<std::ptrdiff_t>(kLevelColumns) &&
         std::abs(x.z() - m) <= kLevelBand;
}
Foot::Kind Foot::at(const Eigen::Vector3f& x, uint32_t object, float base) const {
  if (!low(x.z(), base)) return kBody;
  bool under = false;
  for (int dx = -1; dx <= 1 && !under; ++dx)
    for (int dy = -1; dy <= 1 && !under; ++dy) under = raised_.contains(column(x, object, dx, dy));
  if (!under) return kTouched;
  if (overhead_.standsOn(x, object, base)) return kStoodOn;
  return level(x, base) ? kLevel : kBody;
}

namespace {

bool vehicleSized(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const ObjectParams& p) {
  return cleanmap::vehicleSized(lo, hi, p.max_length, p.max_height);
}

}  // namespace

// Rule 5's objects: the components of the points of `mask`.
void wholeObjectsOf(const std::vector<PointXYZI>& points, const std::vector<uint8_t>& mask,
                    double side, WholeObjects& out, const RingReach& reach) {
  out.voxel.clear();
  out.extent.clear();
  out.centroid.clear();
  out.lo.clear();
  out.hi.clear();
  ObjectComponents cc;
  groupObjects(points, mask, side, cc, reach);
  std::vector<uint32_t> id(cc.voxels.size(), UINT32_MAX), n;
  std::vector<Eigen::Vector3f>&lo = out.lo, &hi = out.hi;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (cc.point_voxel[i] == UINT32_MAX) continue;
    const uint32_t root = cc.root_of[cc.point_voxel[i]];
    if (id[root] == UINT32_MAX) {
      id[root] = static_cast<uint32_t>(lo.size());
      lo.push_back(points[i].xyz());
      hi.push_back(points[i].xyz());
      out.centroid.push_back(Eigen::Vector3f::Zero());
      n.push_back(0);
    }
    const uint32_t a = id[root];
    lo[a] = lo[a].cwiseMin(points[i].xyz());
    hi[a] = hi[a].cwiseMax(points[i].xyz());
    out.centroid[a] += points[i].xyz();
    ++n[a];
  }
  for (std::size_t a = 0; a < lo.size(); ++a) {
    out.extent.push_back(hi[a] - lo[a]);
    out.centroid[a] /= static_cast<float>(n[a]);
  }
  for (uint32_t v = 0; v < cc.voxels.size(); ++v) {
    const Eigen::Vector3i& c = cc.voxels[v];
    out.voxel.get(cellKey(c.x(), c.y(), c.z())) = id[cc.root_of[v]];
  }
}

namespace {

// Whether object a of `objects` holds at least half of q shifted by `shift` (voxels of 1 / inv);
// stops once half is reached or out of reach.
bool holdsHalf(const std::vector<Eigen::Vector3f>& q, const WholeObjects& objects, float inv,
               std::size_t a, const Eigen::Vector3f& shift) {
  std::size_t n = 0, left = q.size();
  for (const Eigen::Vector3f& x : q) {
    if (2 * n >= q.size()) return true;
    if (2 * (n + left) < q.size()) return false;
    --left;
    const Eigen::Vector3f y = x + shift;
    if (const uint32_t* b = objects.voxel.find(
            cellKey(floorToCell(y.x(), inv), floorToCell(y.y(), inv), floorToCell(y.z(), inv))))
      n += *b == a;
  }
  return 2 * n >= q.size();
}

}  // namespace

std::optional<WholeMatch> matchWholeObject(const std::vector<Eigen::Vector3f>& q,
                                           const WholeObjects& objects, double side,
                                           float max_shift) {
  if (q.empty()) return std::nullopt;
  const float inv = static_cast<float>(1.0 / side);
  std::vector<uint32_t> in(objects.extent.size(), 0);
  Eigen::Vector3f c = Eigen::Vector3f::Zero(), lo = Eigen::Vector3f::Constant(1e30f), hi = -lo;
  for (const Eigen::Vector3f& x : q) {
    c += x;
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  // A point in an object's voxel lies within a voxel of its box: where no box is that near, none
  // of them is in one (issue #16: most components asked lie near no object).
  const float margin = static_cast<float>(side) * 1.01f + 1e-3f;
  bool near = objects.lo.size() != objects.extent.size();  // boxes not given: ask every point
  for (std::size_t a = 0; a < objects.lo.size() && !near; ++a)
    near = (lo.array() <= objects.hi[a].array() + margin).all() &&
           (hi.array() >= objects.lo[a].array() - margin).all();
  if (near) {
    uint64_t last_key = CellMap<uint32_t>::kEmpty;  // neighbouring returns mostly share a voxel
    const uint32_t* last = nullptr;
    for (const Eigen::Vector3f& x : q) {
      const uint64_t key =
          cellKey(floorToCell(x.x(), inv), floorToCell(x.y(), inv), floorToCell(x.z(), inv));
      if (key != last_key) {
        last = objects.voxel.find(key);
        last_key = key;
      }
      if (last && 2 * std::size_t(++in[*last]) > q.size())  // more than half: none can tie it
        return WholeMatch{*last, Eigen::Vector3f::Zero()};
    }
  }
  const auto best = std::max_element(in.begin(), in.end());
  if (best == in.end()) return std::nullopt;
  if (2 * std::size_t(*best) >= q.size())
    return WholeMatch{static_cast<std::size_t>(best - in.begin()), Eigen::Vector3f::Zero()};
  // Found moved (a car moving about a voxel a scan no longer lies in its previous voxels; the
  // map's rule 5, DESIGN §2e).
  // A vehicle moves along the road: the centroids' height differs by what each scan's rings
  // hold (a sparse lidar's roof stripe joined in one scan and not the other), so the shift is
  // also tried level.
  c /= static_cast<float>(q.size());
  const auto holds = [&](std::size_t a, const Eigen::Vector3f& shift) {
    return holdsHalf(q, objects, inv, a, shift);
  };
  for (std::size_t a = 0; a < objects.extent.size(); ++a) {
    const Eigen::Vector3f shift = objects.centroid[a] - c;
    const Eigen::Vector3f level(shift.x(), shift.y(), 0.0f);
    if (level.squaredNorm() > max_shift * max_shift) continue;
    if (shift.squaredNorm() <= max_shift * max_shift && holds(a, shift))
      return WholeMatch{a, shift};
    if (shift.z() != 0.0f && holds(a, level)) return WholeMatch{a, level};
  }
  return std::nullopt;
}

std::optional<WholeMatch> matchWholeObjectByEnds(const std::vector<Eigen::Vector3f>& q,
                                                 const WholeObjects& objects, double side,
                                                 float max_shift) {
  if (q.empty() || objects.lo.size() != objects.extent.size()) return std::nullopt;
  const float inv = static_cast<float>(1.0 / side);
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = -lo;
  for (const Eigen::Vector3f& x : q) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  // Each pairing of the boxes' ends in x and in y (lower or upper faces), level.
  for (std::size_t a = 0; a < objects.extent.size(); ++a)
    for (int ex = 0; ex < 2; ++ex)
      for (int ey = 0; ey < 2; ++ey) {
        const Eigen::Vector3f s(ex ? objects.hi[a].x() - hi.x() : objects.lo[a].x() - lo.x(),
                                ey ? objects.hi[a].y() - hi.y() : objects.lo[a].y() - lo.y(), 0.0f);
        if (s.squaredNorm() <= max_shift * max_shift && holdsHalf(q, objects, inv, a, s))
          return WholeMatch{a, s, true};
      }
  return std::nullopt;
}

Eigen::Vector3f ringLifted(Eigen::Vector3f e, const Eigen::Vector3f& x, float step) {
  if (e.z() >= 0.5f * step) e.z() = std::max(e.z(), std::min(x.z(), e.z() + step));
  return e;
}

bool sizedAs(const Eigen::Vector3f& e, const Eigen::Vector3f& x, double tolerance, bool at_most,
             float step) {
  const Eigen::Vector3f l = ringLifted(e, x, step);
  const float eh = l.head<2>().norm(), xh = x.head<2>().norm();
  const double f = 1.0 - tolerance;
  return eh >= f * xh && l.z() >= f * x.z() && (!at_most || xh >= f * eh);
}

std::optional<WholeMatch> matchWholeObjectOrByEnds(const std::vector<Eigen::Vector3f>& q,
                                                   const WholeObjects& objects, double side,
                                                   float max_shift) {
  if (auto m = matchWholeObject(q, objects, side, max_shift)) return m;
  return matchWholeObjectByEnds(q, objects, side, max_shift);
}

ObjectConsensusStats objectConsensus(const std::vector<PointXYZI>& points,
                                     const std::vector<uint8_t>& member,
                                     std::vector<uint8_t>& moving, const ObjectParams& p,
                                     const std::vector<uint8_t>* near_previous,
                                     std::vector<uint8_t>* in_moving_object,
                                     const ConsensusRules& rules, const ObjectComponents* grouped) {
  ObjectConsensusStats st;
  if (in_moving_object) in_moving_object->assign(points.size(), 0);
  if (!p.enabled) return st;
  // Voxels of the member points and their components (26-connected; a sparse lidar's rings).
  ObjectComponents own;
  if (grouped && (grouped->point_voxel.size() != points.size() || grouped->side != p.voxel ||
                  !(grouped->reach == rules.reach)))
    throw std::invalid_argument(
        "objectConsensus: a grouping of " + std::to_string(grouped->point_voxel.size()) +
        " points in voxels of " + std::to_string(grouped->side) + " m (" +
        describe(grouped->reach) + ") given for " + std::to_string(points.size()) +
        " points in voxels of " + std::to_string(p.voxel) + " m (" + describe(rules.reach) + ")");
  if (!grouped) groupObjects(points, member, p.voxel, own, rules.reach);
  const ObjectComponents& cc = grouped ? *grouped : own;
  const std::vector<Eigen::Vector3i>& voxels = cc.voxels;
  const std::vector<uint32_t>& point_voxel = cc.point_voxel;
  const std::vector<uint32_t>& root_of = cc.root_of;
  // The voxels that hold moving points (moving_in[v] > 0), joined with the linked voxels that do
  // (26-neighbours, and a sparse lidar's rings: RingReach): connected groups of moving points.
  const auto movingGroups = [&](const std::vector<uint32_t>& moving_in) {
    UnionFind g(voxels.size());
    for (uint32_t v = 0; v < voxels.size(); ++v) {
      if (!moving_in[v]) continue;
      forEachLinked(cc, v, [&](uint32_t n) {
        if (moving_in[n]) g.unite(v, n);
      });
    }
    return g;
  };
  // Per component: point counts and extent.
  struct Comp {
    std::size_t n = 0, moving = 0, near_prev = 0;
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = Eigen::Vector3f::Constant(-1e30f);
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  };
  std::vector<Comp> comps(voxels.size());
  const std::vector<float> width = componentWidths(cc, p.foot_height);  // per root, rule 2
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (point_voxel[i] == UINT32_MAX) continue;
    Comp& c = comps[root_of[point_voxel[i]]];
    ++c.n;
    c.moving += moving[i] != 0;
    if (near_previous) c.near_prev += (*near_previous)[i] != 0;
    c.lo = c.lo.cwiseMin(points[i].xyz());
    c.hi = c.hi.cwiseMax(points[i].xyz());
    c.sum += points[i].xyz();
  }
  // Rule 5: the share of a component's points in the voxels of a whole object of the adjacent
  // scan, as they are and moved by the two centroids' difference (0 where the sizes differ or
  // the centroids lie more than max_shift apart).
  const WholeObjects* wo = rules.whole_objects;
  std::vector<uint8_t> all_parts;  // per root: another scan's object (rules 4, 5): all parts go
  Grouped members;  // the member points by component, in point order (built once, if needed)
  const auto groupMembers = [&] {
    if (members.size() > 0) return;
    std::vector<uint32_t> root, index;
    for (std::size_t i = 0; i < points.size(); ++i)
      if (point_voxel[i] != UINT32_MAX) {
        root.push_back(root_of[point_voxel[i]]);
        index.push_back(static_cast<uint32_t>(i));
      }
    members.assign(root, voxels.size(), &index);
  };
  const float inv_voxel = static_cast<float>(1.0 / p.voxel);
  const auto shares = [&](uint32_t root, const Comp& c, uint32_t a) {
    const auto close = [&](float x, float y) {
      return std::abs(x - y) <= rules.extent_tolerance * std::max(x, y);
    };
    const Eigen::Vector3f e = c.hi - c.lo, x = wo->extent[a];
    const Eigen::Vector3f shift = wo->centroid[a] - c.sum / static_cast<float>(c.n);
    if (!close(e.head<2>().norm(), x.head<2>().norm()) || !close(e.z(), x.z()) ||
        shift.norm() > rules.max_shift)
      return std::pair(0.0, 0.0);
    groupMembers();
    const auto in = [&](const Eigen::Vector3f& q) {
      const uint32_t* o =
          wo->voxel.find(cellKey(floorToCell(q.x(), inv_voxel), floorToCell(q.y(), inv_voxel),
                                 floorToCell(q.z(), inv_voxel)));
      return o && *o == a;
    };
    std::size_t as_is = 0, moved = 0;
    for (const uint32_t i : members[root]) {
      const Eigen::Vector3f q = points[i].xyz();
      as_is += in(q);
      moved += in(q + shift);
    }
    const double n = static_cast<double>(c.n);
    return std::pair(static_cast<double>(as_is) / n, static_cast<double>(moved) / n);
  };
  if (wo && !wo->empty()) all_parts.assign(voxels.size(), 0);
  std::vector<uint8_t> turn(voxels.size(), 0);  // 1: all moving, 2: all static
  std::vector<uint8_t> whole;                   // vehicle-sized, moving in every point
  if (in_moving_object) whole.assign(voxels.size(), 0);
  // A caller's rule (has_left, was_whole, measured) asked of component v's points.
  const auto ask = [&](const std::function<bool(const std::vector<uint32_t>&)>& rule, uint32_t v) {
    groupMembers();
    return rule(std::vector<uint32_t>(members[v].begin(), members[v].end()));
  };
  // Rule 2's previous scan's object: per root, 1 to ask was_whole where a part above its foot
  // has no moving point (asked there, once: a mover moving in every part is not), 2 once it is.
  std::vector<uint8_t> ask_whole;
  const auto wasWhole = [&](uint32_t v) {
    if (ask_whole[v] == 1) ask_whole[v] = ask(rules.was_whole, v) ? 2 : 0;
    return ask_whole[v] == 2;
  };
  const bool few_are_noise = rules.few_points_are_noise;
  // Rule 2's far exception (doc/OBJECTS.md, "Far and few"): past 10 m a walker returns fewer than
  // min_moving points to an HDL-64E, and the windowed test flags nearly all of them. Returns
  // narrower than 0.3 m are left to the rules: a pose error of a few centimetres empties a thin
  // pole whole (poles_drift), not a body wider than twice sigma_r. The body of the recording car
  // (13-49 returns a scan within 2 m, flagged whole as it moves with the sensor) is nearer.
  constexpr float kFarRange = 10.0f, kFarWidth = 0.3f;
  std::vector<uint8_t> far_kept;  // per root: moving points kept (not noise for rules 2 and 3)
  const auto farAndFew = [&](const Comp& c) {
    const int flagged = static_cast<int>(c.moving);
    if (!few_are_noise || !rules.far_window || p.far_points <= 0 || flagged >= p.min_moving ||
        flagged < p.far_points || 10 * c.moving < 9 * c.n ||
        (c.hi - c.lo).head<2>().norm() < kFarWidth)
      return false;
    return (c.sum / static_cast<float>(c.n)).head<2>().norm() >= kFarRange;
  };
  bool body_check = false;  // a component turned static holds enough moving points for a body
  for (uint32_t v = 0; v < voxels.size(); ++v) {
    const Comp& c = comps[v];
    if (c.n == 0) continue;
    ++st.objects;
    const bool vehicle_sized = vehicleSized(c.lo, c.hi, p);
    // Rule 2's width: what is wider than any vehicle never moves as a whole (doc/OBJECTS.md).
    const bool wide = width[v] > p.max_width;
    const bool movable = vehicle_sized && !wide;
    if (in_moving_object)
      whole[v] = vehicle_sized && c.moving == c.n && static_cast<int>(c.n) >= p.min_moving;
    // Partly moving with at least min_moving points and `share` of them.
    const auto share_of = [&](double share) {
      return static_cast<int>(c.moving) >= p.min_moving &&
             static_cast<double>(c.moving) >= share * static_cast<double>(c.n) && c.moving < c.n;
    };
    const auto partly = [&](double share) { return movable && share_of(share); };
    if (vehicle_sized && wide && share_of(p.static_fraction))
      ++st.wide_objects_left;  // a share the rules below would weigh
    if (partly(p.moving_fraction)) {
      turn[v] = 1;
      ++st.moving_objects;
      if (rules.was_whole && p.persist_radius > 0 && 2 * c.near_prev >= c.n) {
        // If it is the object the previous scan moved whole, all of its parts go, as under
        // rules 4 and 5 (doc/OBJECTS.md rule 2, "The previous scan's object"; asked below).
        if (ask_whole.empty()) ask_whole.assign(voxels.size(), 0);
        ask_whole[v] = 1;
      }
    } else if (p.persist_radius > 0 && partly(p.static_fraction) && 2 * c.near_prev >= c.n) {
      turn[v] = 1;  // hysteresis: it moved in the previous scan and is still partly moving
      ++st.moving_objects;
      ++st.persisted;
    } else if (rules.has_left && p.persist_radius > 0 && movable && c.moving < c.n &&
               2 * c.near_prev >= c.n && ask(rules.has_left, v)) {
      // Rule 4 under static_fraction: it moved before and has left where it is now (or the
      // scans after it are too few to tell); has_left says what leaving takes (the caller's).
      // It is the previous scan's object: every part goes, as under rule 5.
      turn[v] = 1;
      if (all_parts.empty()) all_parts.assign(voxels.size(), 0);
      all_parts[v] = 1;
      ++st.moving_objects;
      ++st.persisted;
      ++st.left_place;
    } else if (rules.measured && movable && c.moving < c.n && c.n >= rules.measured_points &&
               static_cast<double>(c.moving) < p.moving_fraction * static_cast<double>(c.n) &&
               ask(rules.measured, v)) {
      // Rule 7: its outline moved between the scans half a window before and after it.
      turn[v] = 1;
      if (all_parts.empty()) all_parts.assign(voxels.size(), 0);
      all_parts[v] = 1;
      ++st.moving_objects;
      ++st.measured;
    } else if (vehicle_sized && farAndFew(c)) {
      if (far_kept.empty()) far_kept.assign(voxels.size(), 0);
      far_kept[v] = 1;  // its labels stay, rule 3's groups too
      ++st.far_kept;
    } else if (vehicle_sized && c.moving > 0 && (cc.piece.empty() || !cc.piece[v]) &&
               ((few_are_noise && static_cast<int>(c.moving) < p.min_moving) ||
                static_cast<double>(c.moving) < p.static_fraction * static_cast<double>(c.n))) {
      turn[v] = 2;
      body_check = body_check || static_cast<int64_t>(c.moving) >= 5 * int64_t(p.min_moving);
    }
  }
  // Rule 5. A component that shares its voxels with a whole object of its size is that object:
  // two solids do not share their space. One that would, moved by the centroids' difference, may
  // be that object moved (a car keeping its distance to the sensor shows the same faces), or its
  // neighbour of the same size (parked cars in a row): a whole object of this scan that matches
  // the other scan's object claims it, and an unclaimed one takes the best of its candidates.
  if (wo && !wo->empty()) {
    const auto candidate = [&](uint32_t v) {
      const Comp& c = comps[v];
      return c.n > 0 && turn[v] != 1 && c.moving < c.n && static_cast<int>(c.n) >= p.min_moving &&
             vehicleSized(c.lo, c.hi, p) && !(width[v] > p.max_width);
    };
    const auto isWhole = [&](uint32_t v) {
      const Comp& c = comps[v];
      return c.n > 0 && vehicleSized(c.lo, c.hi, p) &&
             (turn[v] == 1 || (c.moving == c.n && static_cast<int>(c.n) >= p.min_moving));
    };
    const std::size_t na = wo->extent.size();
    std::vector<uint8_t> claimed(na, 0);
    std::vector<double> best(na, 0.0);
    std::vector<uint32_t> best_of(na, UINT32_MAX);
    const double need = rules.overlap_fraction;
    for (uint32_t v = 0; v < voxels.size(); ++v) {
      if (!isWhole(v) && !candidate(v)) continue;
      const bool whole_now = isWhole(v);
      for (uint32_t a = 0; a < na; ++a) {
        const auto [as_is, moved] = shares(v, comps[v], a);
        if (whole_now) {
          claimed[a] = claimed[a] || std::max(as_is, moved) >= need;
        } else if (as_is >= need) {
          all_parts[v] = 1;  // in the same voxels: the same object
        } else if (moved >= need && moved > best[a]) {
          best[a] = moved;
          best_of[a] = v;
        }
      }
    }
    for (uint32_t a = 0; a < na; ++a)
      if (!claimed[a] && best_of[a] != UINT32_MAX) all_parts[best_of[a]] = 1;
    for (uint32_t v = 0; v < voxels.size(); ++v)
      if (all_parts[v] && turn[v] != 1) {
        turn[v] = 1;
        ++st.moving_objects;
        ++st.persisted;
      }
  }
  // Bodies (doc/OBJECTS.md, rule 2's exception): connected groups of voxels holding moving points,
  // with at least 5 min_moving moving points that are at least half of their voxels' points. A
  // body touching a static surface (a walker against a wall) joins its component; alarms on a
  // static object share their voxels with its other returns.
  std::vector<uint32_t> body_of, group_moving, group_all;  // per voxel: its group's root
  if (body_check) {
    body_of.assign(voxels.size(), UINT32_MAX);
    group_moving.assign(voxels.size(), 0);
    group_all.assign(voxels.size(), 0);
    std::vector<uint32_t> in_voxel(voxels.size(), 0), moving_in_voxel(voxels.size(), 0);
    for (std::size_t i = 0; i < points.size(); ++i)
      if (point_voxel[i] != UINT32_MAX) {
        ++in_voxel[point_voxel[i]];
        moving_in_voxel[point_voxel[i]] += moving[i] != 0;
      }
    UnionFind guf = movingGroups(moving_in_voxel);
    for (uint32_t v = 0; v < voxels.size(); ++v)
      if (moving_in_voxel[v]) {
        body_of[v] = guf.find(v);
        group_moving[body_of[v]] += moving_in_voxel[v];
        group_all[body_of[v]] += in_voxel[v];
      }
  }
  const auto in_body = [&](uint32_t voxel) {
    if (!body_check) return false;
    const uint32_t g = body_of[voxel];
    return g != UINT32_MAX && static_cast<int64_t>(group_moving[g]) >= 5 * int64_t(p.min_moving) &&
           2 * group_moving[g] >= group_all[g];
  };
  // Rule 2's spread stops at the component's foot (doc/OBJECTS.md): a point less than foot_height
  // above the component's lowest with no point of the component at or above that height in its
  // 3 x 3 column of voxels is a low surface the object touches, not a part of it (from 0.8 m a
  // sidewalk 0.12 m up, not ground, joins a car that leaves the curb). A vehicle's low parts,
  // its wheels and sills, have its body above them.
  // Above the foot, the component falls apart into the parts connected there: low surfaces (a
  // sidewalk that is not ground) join a walker to the pole and the wall beside it, and the
  // spread turns only the parts that hold a moving point of their own, not the pole and the wall
  // (doc/OBJECTS.md rule 2). (A share of 10 % instead lost kitti_highway 0.0024 of its recall,
  // parts of trucks with few moving points.)
  // The points of the components turned moving, per component; columns raised by the parts the
  // spread reaches.
  Foot foot(cc.side, p.foot_height, p.foot_reach, rules.reach.ring_gap, rules.stand_top);
  const auto low = [&](std::size_t i, uint32_t root) {
    return foot.low(points[i].z, comps[root].lo.z());
  };
  std::vector<uint8_t> spreads;   // per voxel (a raised part's root): the spread reaches it
  std::vector<uint32_t> part_of;  // per voxel: its raised part's root (UINT32_MAX: none)
  if (p.foot_height > 0 && st.moving_objects > 0) {  // no component turned moving: no foot to find
    std::vector<uint32_t> raised_in(voxels.size(), 0), raised_moving(voxels.size(), 0);
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (point_voxel[i] == UINT32_MAX) continue;
      const uint32_t root = root_of[point_voxel[i]];
      if (turn[root] != 1 || low(i, root)) continue;
      ++raised_in[point_voxel[i]];
      raised_moving[point_voxel[i]] += moving[i] != 0;
    }
    UnionFind parts = movingGroups(raised_in);  // voxels with raised points, 26-connected
    part_of.assign(voxels.size(), UINT32_MAX);
    std::vector<uint32_t> part_n(voxels.size(), 0), part_moving(voxels.size(), 0);
    for (uint32_t v = 0; v < voxels.size(); ++v)
      if (raised_in[v]) {
        part_of[v] = parts.find(v);
        part_n[part_of[v]] += raised_in[v];
        part_moving[part_of[v]] += raised_moving[v];
      }
    spreads.assign(voxels.size(), 0);
    for (uint32_t v = 0; v < voxels.size(); ++v)
      if (part_n[v] > 0)
        spreads[v] = part_moving[v] > 0 || (!all_parts.empty() && all_parts[root_of[v]]) ||
                     (!ask_whole.empty() && wasWhole(root_of[v]));
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (point_voxel[i] == UINT32_MAX) continue;
      const uint32_t root = root_of[point_voxel[i]];
      if (turn[root] != 1) continue;
      foot.add(points[i].xyz(), root, comps[root].lo.z(),
               !low(i, root) && spreads[part_of[point_voxel[i]]]);
    }
    // "Level with the surface around it": the other components' points in the heights of the
    // turned ones' foot bands (Foot::level reads no others).
    if (foot.levels()) {
      float band_lo = std::numeric_limits<float>::max(), band_hi = -band_lo;
      for (uint32_t v = 0; v < voxels.size(); ++v)
        if (turn[v] == 1 && comps[v].n > 0) {
          band_lo = std::min(band_lo, comps[v].lo.z() - static_cast<float>(p.foot_height));
          band_hi = std::max(band_hi, comps[v].lo.z() + static_cast<float>(p.foot_height));
        }
      for (std::size_t i = 0; i < points.size(); ++i)
        if (point_voxel[i] != UINT32_MAX && points[i].z > band_lo && points[i].z < band_hi &&
            turn[root_of[point_voxel[i]]] != 1)
          foot.addAround(points[i].xyz());
    }
    foot.settle();
  }
  // A raised point of a part the spread does not reach.
  const auto still_part = [&](std::size_t i, uint32_t root) {
    return !spreads.empty() && !low(i, root) && !spreads[part_of[point_voxel[i]]];
  };
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (point_voxel[i] == UINT32_MAX) continue;
    const uint32_t root = root_of[point_voxel[i]];
    const uint8_t t = turn[root];
    if (t == 1 && !moving[i]) {
      if (const Foot::Kind kind = foot.at(points[i].xyz(), root, comps[root].lo.z())) {
        ++st.foot_points_left;
        st.surface_points_left += kind >= Foot::kStoodOn;
        continue;
      }
      if (still_part(i, root)) {
        ++st.still_part_points_left;
        continue;
      }
      moving[i] = 1;
      ++st.points_added;
    } else if (t == 2 && moving[i]) {
      if (in_body(point_voxel[i])) {
        ++st.body_points_kept;
        continue;
      }
      moving[i] = 0;
      ++st.points_removed;
    }
  }
  if (in_moving_object)
    for (std::size_t i = 0; i < points.size(); ++i)
      if (point_voxel[i] != UINT32_MAX) {
        const uint32_t root = root_of[point_voxel[i]];
        (*in_moving_object)[i] = turn[root] == 1 || whole[root];
      }
  // Inside structures (too large for the rule above), moving points count only in groups: a
  // connected group of moving points smaller than min_moving is static.
  if (!few_are_noise) return st;
  std::vector<uint32_t> moving_in(voxels.size(), 0);
  for (std::size_t i = 0; i < points.size(); ++i)
    if (point_voxel[i] != UINT32_MAX && moving[i]) ++moving_in[point_voxel[i]];
  UnionFind muf = movingGroups(moving_in);
  std::vector<uint32_t> group(voxels.size(), 0);
  for (uint32_t v = 0; v < voxels.size(); ++v)
    if (moving_in[v]) group[muf.find(v)] += moving_in[v];
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (point_voxel[i] == UINT32_MAX || !moving[i]) continue;
    if (!far_kept.empty() && far_kept[root_of[point_voxel[i]]]) continue;
    if (static_cast<int>(group[muf.find(point_voxel[i])]) < p.min_moving) {
      moving[i] = 0;
      ++st.points_removed;
    }
  }
  return st;
}

std::vector<uint8_t> inVehicleSizedObject(const std::vector<PointXYZI>& points,
                                          const std::vector<uint8_t>& member, const ObjectParams& p,
                                          const RingReach& reach) {
  std::vector<uint8_t> in(points.size(), 0);
  if (!p.enabled) return in;
  ObjectComponents cc;
  groupObjects(points, member, p.voxel, cc, reach);
  std::vector<Eigen::Vector3f> lo(cc.voxels.size(), Eigen::Vector3f::Constant(1e30f)),
      hi(cc.voxels.size(), Eigen::Vector3f::Constant(-1e30f));
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (cc.point_voxel[i] == UINT32_MAX) continue;
    const uint32_t root = cc.root_of[cc.point_voxel[i]];
    lo[root] = lo[root].cwiseMin(points[i].xyz());
    hi[root] = hi[root].cwiseMax(points[i].xyz());
  }
  for (std::size_t i = 0; i < points.size(); ++i)
    if (cc.point_voxel[i] != UINT32_MAX) {
      const uint32_t root = cc.root_of[cc.point_voxel[i]];
      in[i] = vehicleSized(lo[root], hi[root], p);
    }
  return in;
}

void persistCells(const std::vector<PointXYZI>& points, const std::vector<uint8_t>* mask,
                  double radius, CellMap<uint8_t>& cells) {
  cells.clear();
  const double inv = 1.0 / radius;
  CellMap<uint8_t> own;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!mask || (*mask)[i])
      own.insert(cellKeyOf(double(points[i].x), double(points[i].y), double(points[i].z), inv));
  own.forEach([&](uint64_t c, uint8_t) {
    forEachNeighbour27([&](int dx, int dy, int dz) { cells.insert(cellKeyShift(c, dx, dy, dz)); });
  });
}

// One scan with the memory of the scan decided before it in this direction (the previous one
// forwards, the next one backwards).
ObjectConsensusStats MapObjectConsensus::run(Memory& m, bool backward, int64_t scan, double density,
                                             const RingReach& reach,
                                             const std::vector<PointXYZI>& points,
                                             const std::vector<uint8_t>& member,
                                             std::vector<uint8_t>& removed, std::size_t fixed_from,
                                             const ObjectComponents* grouped) {
  if (!p_.enabled) return {};
  const int64_t e = epochOf(scan);
  if (e != m.epoch) m = Memory{};  // DESIGN §2f: no memory crosses an epoch's start, either way
  m.epoch = e;
  ConsensusRules rules;
  rules.few_points_are_noise = false;  // a removal is a voxel the sequence saw empty, no alarm
  rules.reach = reach;
  const bool persist = p_.persist_radius > 0 && !m.cells.empty();
  if (persist) {
    const double inv = 1.0 / p_.persist_radius;
    near_.assign(points.size(), 0);
    for (std::size_t i = 0; i < points.size(); ++i)
      near_[i] = member[i] && m.cells.contains(cellKeyOf(double(points[i].x), double(points[i].y),
                                                         double(points[i].z), inv));
  }
  if (overlap_ > 0 && !m.objects.empty()) {
    rules.whole_objects = &m.objects;
    rules.overlap_fraction = overlap_;
  }
  ObjectParams op = p_;  // min_moving is an HDL-64E count (§2d)
  op.min_moving = scaledCount(op.min_moving, density);
  decided_ = removed;
  ObjectConsensusStats st = objectConsensus(points, member, decided_, op,
                                            persist ? &near_ : nullptr, &whole_, rules, grouped);
  st.points_added = st.points_removed = 0;
  for (std::size_t i = 0; i < std::min(fixed_from, removed.size()); ++i) {
    if (backward && !decided_[i]) continue;  // backwards only adds (decide() kept the rest)
    st.points_added += decided_[i] && !removed[i];
    st.points_removed += removed[i] && !decided_[i];
    removed[i] = decided_[i];
  }
  // The memory: the objects removed whole, not the free space's scattered removals (a parked car
  // seen through its windows loses a few points in every scan).
  if (p_.persist_radius > 0) persistCells(points, &whole_, p_.persist_radius, m.cells);
  if (overlap_ > 0) wholeObjectsOf(points, whole_, p_.voxel, m.objects, reach);
  return st;
}

}  // namespace cleanmap
