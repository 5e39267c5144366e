// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/mover_feet.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "cleanmap/core/fast_math.h"
#include "cleanmap/core/median.h"

namespace cleanmap {
namespace {

constexpr uint32_t kNone = UINT32_MAX;
constexpr double kMaxRoadReach = 6.0;  // m; how far a foot's road is looked for (rule 6)

// Items in square horizontal cells over a box of the world's xy plane, a flat array of list
// heads threaded through `next` (a scan's few thousand movers or road returns: no hashing).
class FlatLists {
 public:
  // Cells on the world's grid of `side` (floor(x / side)), those meeting `box`.
  FlatLists(const Eigen::AlignedBox2d& box, double side) : inv_(1.0 / side) {
    i0_ = static_cast<int64_t>(std::floor(box.min().x() * inv_));
    j0_ = static_cast<int64_t>(std::floor(box.min().y() * inv_));
    nx_ = static_cast<int64_t>(std::floor(box.max().x() * inv_)) - i0_ + 1;
    ny_ = static_cast<int64_t>(std::floor(box.max().y() * inv_)) - j0_ + 1;
    head_.assign(static_cast<std::size_t>(nx_ * ny_), kNone);
  }
  // The cell of q; -1 outside the box.
  int64_t cell(double x, double y) const {
    const auto i = static_cast<int64_t>(std::floor(x * inv_)) - i0_;
    const auto j = static_cast<int64_t>(std::floor(y * inv_)) - j0_;
    return i < 0 || j < 0 || i >= nx_ || j >= ny_ ? -1 : i * ny_ + j;
  }
  uint32_t& head(int64_t c) { return head_[static_cast<std::size_t>(c)]; }
  std::size_t cells() const { return head_.size(); }
  void add(int64_t c, uint32_t item) {
    if (next.size() <= item) next.resize(item + 1);
    next[item] = head(c);
    head(c) = item;
  }
  // Calls f(item) for the items of the 3 x 3 cells around cell c, each cell's in list order
  // until f returns false.
  template <class F>
  void around(int64_t c, F&& f) const {
    const int64_t i = c / ny_, j = c % ny_;
    for (int64_t a = std::max<int64_t>(0, i - 1); a <= std::min(nx_ - 1, i + 1); ++a)
      for (int64_t b = std::max<int64_t>(0, j - 1); b <= std::min(ny_ - 1, j + 1); ++b)
        for (uint32_t k = head_[static_cast<std::size_t>(a * ny_ + b)]; k != kNone && f(k);
             k = next[k]) {
        }
  }
  // Calls f(item) for the items of the cells k cells from cell c (the square ring of them).
  template <class F>
  void ring(int64_t c, int64_t k, F&& f) const {
    const int64_t i = c / ny_, j = c % ny_;
    const auto cell = [&](int64_t a, int64_t b) {
      if (a < 0 || b < 0 || a >= nx_ || b >= ny_) return;
      for (uint32_t m = head_[static_cast<std::size_t>(a * ny_ + b)]; m != kNone; m = next[m]) f(m);
    };
    for (int64_t b = j - k; b <= j + k; ++b) cell(i - k, b), cell(i + k, b);
    for (int64_t a = i - k + 1; a < i + k; ++a) cell(a, j - k), cell(a, j + k);
  }
  std::vector<uint32_t> next;

 private:
  double inv_;
  int64_t i0_ = 0, j0_ = 0, nx_ = 0, ny_ = 0;
  std::vector<uint32_t> head_;
};

}  // namespace

std::vector<uint32_t> moverFeet(const std::vector<PointXYZI>& points, const Eigen::Isometry3d& pose,
                                const std::vector<uint8_t>& ground,
                                const std::vector<uint8_t>& moving,
                                const std::vector<uint8_t>& in_crop, const MoverFeetParams& p,
                                const std::vector<Eigen::Vector3d>* known) {
  const std::size_t n = points.size();
  if (known && known->size() != n)
    throw std::invalid_argument("moverFeet: " + std::to_string(known->size()) +
                                " world coordinates given for " + std::to_string(n) + " points");
  auto world = [&](std::size_t i) -> Eigen::Vector3d {
    return pose * points[i].xyz().cast<double>();
  };
  // A non-ground point in the crop: as the caller computed it, where it did (the same bits).
  auto raised = [&](std::size_t i) -> Eigen::Vector3d { return known ? (*known)[i] : world(i); };
  // The refined ground points in the crop, and how high over them a mover can be to stand on
  // them: only the movers up to there are indexed (a truck's lowest metre, not its side).
  struct Candidate {
    uint32_t i;
    Eigen::Vector3d q;
    double up;
  };
  std::vector<Candidate> cand;
  double reach = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i) {
    if (ground[i] != kGroundRefined || !in_crop[i]) continue;
    const double range = std::hypot(double(points[i].x), double(points[i].y));
    cand.push_back({static_cast<uint32_t>(i), world(i), std::max(0.3, 2.0 * range * p.ring_gap)});
    reach = std::max(reach, cand.back().q.z() + cand.back().up);
  }
  if (cand.empty()) return {};
  // The moving returns within reach, and the others near them, in cells of `radius` over the
  // movers' box.
  std::vector<Eigen::Vector3d> above;
  std::vector<uint8_t> above_moving;
  Eigen::AlignedBox2d mov_box;
  for (std::size_t i = 0; i < n; ++i)
    if (moving[i] && !ground[i] && in_crop[i]) {
      const Eigen::Vector3d q = raised(i);
      if (q.z() > reach) continue;
      above.push_back(q);
      above_moving.push_back(1);
      mov_box.extend(q.head<2>());
    }
  if (above.empty()) return {};
  // A foot lies within `radius` of a mover; the returns nearer to it, within 2 `radius`.
  const Eigen::AlignedBox2d near_movers(mov_box.min().array() - p.radius,
                                        mov_box.max().array() + p.radius);
  const Eigen::AlignedBox2d indexed(mov_box.min().array() - 2 * p.radius,
                                    mov_box.max().array() + 2 * p.radius);
  for (std::size_t i = 0; i < n; ++i)
    if (!moving[i] && !ground[i] && in_crop[i]) {
      const Eigen::Vector3d q = raised(i);
      if (q.z() > reach || !indexed.contains(q.head<2>())) continue;
      above.push_back(q);
      above_moving.push_back(0);
    }
  // Cells of `radius` (3 x 3 of them hold every return within it), coarser where a long crop
  // would make their array large (the same returns found, a few more looked at).
  const double area = indexed.sizes().prod();
  FlatLists returns(indexed, std::max(p.radius, std::sqrt(area / double(1 << 20))));
  returns.next.resize(above.size());
  for (uint32_t m = 0; m < above.size(); ++m)
    returns.add(returns.cell(above[m].x(), above[m].y()), m);

  // Refined ground points whose nearest return above (horizontally, within `radius` and reach) is
  // moving: the surface going on down to them is a mover's.
  std::vector<uint32_t> under;
  std::vector<Eigen::Vector3d> under_w;
  Eigen::AlignedBox2d under_box;
  const double r2 = p.radius * p.radius;
  for (const Candidate& k : cand) {
    const Eigen::Vector3d& q = k.q;
    if (!near_movers.contains(q.head<2>())) continue;
    double best = 0;
    bool best_moving = false, any = false;
    returns.around(returns.cell(q.x(), q.y()), [&](uint32_t m) {
      const double dz = above[m].z() - q.z();
      if (dz <= 0 || dz > k.up) return true;
      const double d2 = (above[m].head<2>() - q.head<2>()).squaredNorm();
      if (d2 <= r2 && (!any || d2 < best || (d2 == best && !above_moving[m]))) {  // ties: static
        best = d2;
        best_moving = above_moving[m] != 0;
        any = true;
      }
      return true;
    });
    if (any && best_moving) {
      under.push_back(k.i);
      under_w.push_back(q);
      under_box.extend(q.head<2>());
    }
  }
  if (under.empty()) return {};

  // The road around each: the other ground returns in the 3 x 3 ground cells around it; where
  // they hold too few, those in the cells out to where the lidar's next ring down meets a flat
  // road (a VLP-16's rings 17 m off land 4.5 m apart: a car's lowest ring over the road has no
  // road return within a cell of it), at most kMaxRoadReach.
  const double grow = kMaxRoadReach + p.cell;
  FlatLists road(
      Eigen::AlignedBox2d(under_box.min().array() - grow, under_box.max().array() + grow), p.cell);
  const Eigen::Vector3d sensor = pose.translation();
  const auto roadReach = [&](uint32_t i, const Eigen::Vector3d& q) {
    const double d = std::hypot(double(points[i].x), double(points[i].y));
    const double h = sensor.z() - q.z(), down = std::atan2(h, d) + p.ring_gap;
    if (h <= 0 || down >= 0.5 * M_PI) return 0.0;
    return std::min(kMaxRoadReach, d - h / std::tan(down));
  };
  std::vector<uint8_t> is_under(n, 0);
  for (uint32_t i : under) is_under[i] = 1;
  std::vector<float> road_z;
  for (std::size_t i = 0; i < n; ++i) {
    if (!ground[i] || is_under[i]) continue;
    const Eigen::Vector3d q = world(i);
    const int64_t c = road.cell(q.x(), q.y());
    if (c < 0) continue;
    road.add(c, static_cast<uint32_t>(road_z.size()));
    road_z.push_back(static_cast<float>(q.z()));
  }

  // Per road cell, the height a foot must rise over (the road's median and the least rise; +inf
  // with too little road to tell a raised return from it): the feet in one cell share their
  // 3 x 3 block. NaN: not computed yet.
  std::vector<float> level(road.cells(), std::numeric_limits<float>::quiet_NaN());
  std::vector<float> zs;
  std::vector<uint32_t> feet;
  for (std::size_t u = 0; u < under.size(); ++u) {
    const int64_t c = road.cell(under_w[u].x(), under_w[u].y());
    const auto cu = static_cast<std::size_t>(c);
    if (std::isnan(level[cu])) {
      zs.clear();
      road.around(c, [&](uint32_t j) {
        zs.push_back(road_z[j]);
        return true;
      });
      const auto far = static_cast<int64_t>(std::ceil(roadReach(under[u], under_w[u]) / p.cell));
      for (int64_t k = 2; zs.size() < 5 && k <= far; ++k)
        road.ring(c, k, [&](uint32_t j) { zs.push_back(road_z[j]); });
      level[cu] = std::numeric_limits<float>::infinity();
      if (zs.size() >= 5) {
        const float mid = median(zs);
        for (auto& z : zs) z = std::abs(z - mid);
        const double scatter = kMadToSigma * median(zs);
        level[cu] = static_cast<float>(mid + std::max(p.rise, 3.0 * scatter));
      }
    }
    if (under_w[u].z() > level[cu]) feet.push_back(under[u]);
  }
  return feet;
}

std::vector<uint32_t> moverRoofs(const std::vector<PointXYZI>& points,
                                 const Eigen::Isometry3d& pose, const ObjectComponents& cc,
                                 const std::vector<uint8_t>& moving,
                                 const std::vector<uint8_t>& whole,
                                 const std::vector<uint8_t>& ground, const MoverRoofParams& p) {
  std::vector<uint32_t> out;
  if (p.ring_gap <= 0 || cc.voxels.empty()) return out;
  const Eigen::Matrix3d R = pose.linear();  // levelled: heights and horizontal ranges
  const auto rootOf = [&](uint32_t i) {
    return i < cc.point_voxel.size() && cc.point_voxel[i] != UINT32_MAX
               ? cc.root_of[cc.point_voxel[i]]
               : UINT32_MAX;
  };
  // Per component (by its root voxel): points, moving, moving whole; its elevations (sensor).
  struct Component {
    uint32_t n = 0, moving = 0, whole = 0;
    float el_lo = std::numeric_limits<float>::infinity(), el_hi = -el_lo;
  };
  std::vector<Component> comp(cc.voxels.size());
  for (uint32_t i = 0; i < points.size(); ++i) {
    const uint32_t r = rootOf(i);
    if (r == UINT32_MAX) continue;
    Component& c = comp[r];
    ++c.n;
    c.moving += moving[i] != 0;
    c.whole += moving[i] && whole[i];
  }
  // Nothing moving whole and no slice the test flags in part (below): nothing to do.
  const auto flaggedInPart = [&](const Component& c) {
    return c.moving > 0 && c.moving < c.n && c.moving >= p.flagged * c.n;
  };
  if (std::none_of(comp.begin(), comp.end(), [&](const Component& c) {
        return (c.n > 0 && 10 * c.whole >= 9 * c.n) || (!p.dense && flaggedInPart(c));
      }))
    return out;
  for (uint32_t i = 0; i < points.size(); ++i) {
    const uint32_t r = rootOf(i);
    if (r == UINT32_MAX || comp[r].moving == comp[r].n || comp[r].n < 3) continue;
    // A dense lidar's many static returns with the fast angle (issue #16; 3e-7 rad off, under a
    // thousandth of its half ring step); a sparse lidar's as they were.
    const float el = p.dense ? fast::atan2(points[i].z, std::sqrt(points[i].x * points[i].x +
                                                                  points[i].y * points[i].y))
                             : std::atan2(points[i].z, std::hypot(points[i].x, points[i].y));
    comp[r].el_lo = std::min(comp[r].el_lo, el);
    comp[r].el_hi = std::max(comp[r].el_hi, el);
  }
  // The vehicles (moving whole), and the stripes: on one ring, not moving in every point.
  struct Vehicle {
    double sx = 0, sy = 0, r_lo = 1e30, r_hi = 0, top = -1e30, bottom = 1e30, az_lo = 1e30,
           az_hi = -1e30;
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e30), hi = Eigen::Vector2d::Constant(-1e30);
  };
  std::vector<int32_t> vehicle_of(cc.voxels.size(), -1);
  std::vector<Vehicle> vehicles;
  const float half_step = static_cast<float>(0.5 * p.ring_gap);
  std::vector<uint32_t> stripe_points;
  for (uint32_t i = 0; i < points.size(); ++i) {
    const uint32_t r = rootOf(i);
    if (r == UINT32_MAX) continue;
    const Component& c = comp[r];
    if (10 * c.whole < 9 * c.n) {
      if (c.moving < c.n && c.n >= 3 && c.el_hi - c.el_lo <= half_step) stripe_points.push_back(i);
      continue;
    }
    if (vehicle_of[r] < 0) {
      vehicle_of[r] = static_cast<int32_t>(vehicles.size());
      vehicles.emplace_back();
    }
    Vehicle& v = vehicles[static_cast<std::size_t>(vehicle_of[r])];
    const Eigen::Vector3d q = R * points[i].xyz().cast<double>();
    const double range = std::hypot(q.x(), q.y());
    v.sx += q.x() / std::max(range, 1e-6);
    v.sy += q.y() / std::max(range, 1e-6);
    v.r_lo = std::min(v.r_lo, range);
    v.r_hi = std::max(v.r_hi, range);
    v.top = std::max(v.top, q.z());
    v.bottom = std::min(v.bottom, q.z());
    v.lo = v.lo.cwiseMin(q.head<2>());
    v.hi = v.hi.cwiseMax(q.head<2>());
  }
  if (stripe_points.empty()) return out;
  const auto relative = [](double az, double mean) {
    double d = az - mean;
    if (d > M_PI) d -= 2.0 * M_PI;
    if (d < -M_PI) d += 2.0 * M_PI;
    return d;
  };
  std::vector<double> mean(vehicles.size());
  for (std::size_t k = 0; k < vehicles.size(); ++k)
    mean[k] = std::atan2(vehicles[k].sy, vehicles[k].sx);
  // At a dense lidar, per vehicle, the elevation of its highest return in each 0.5-degree bin of
  // azimuth (relative to its mean): a ring lands on its roof only over its top in that column,
  // and a stripe behind a vehicle taller than the sensor lies under the rings that met it
  // (kitti_highway: a truck beside the sensor, its top 0.66 m over it, and a sign's stripe 4-6 m
  // beyond it at 2 degrees). Its returns' azimuths and elevations are kept from the pass below.
  struct Column {
    uint32_t k;
    float d, el;
  };
  std::vector<Column> columns;
  for (uint32_t i = 0; i < points.size(); ++i) {
    const uint32_t r = rootOf(i);
    if (r == UINT32_MAX || vehicle_of[r] < 0) continue;
    const std::size_t k = static_cast<std::size_t>(vehicle_of[r]);
    const Eigen::Vector3d q = R * points[i].xyz().cast<double>();
    const double d = relative(
        p.dense ? double(fast::atan2(float(q.y()), float(q.x()))) : std::atan2(q.y(), q.x()),
        mean[k]);
    vehicles[k].az_lo = std::min(vehicles[k].az_lo, d);
    vehicles[k].az_hi = std::max(vehicles[k].az_hi, d);
    if (p.dense) {
      const float h = std::sqrt(static_cast<float>(q.x() * q.x() + q.y() * q.y()));
      columns.push_back({static_cast<uint32_t>(k), static_cast<float>(d),
                         fast::atan2(static_cast<float>(q.z()), h)});
    }
  }
  constexpr double kAzBin = 0.5 * M_PI / 180;
  std::vector<std::vector<float>> top_el(p.dense ? vehicles.size() : 0);
  for (std::size_t k = 0; k < top_el.size(); ++k)
    top_el[k].assign(static_cast<std::size_t>((vehicles[k].az_hi - vehicles[k].az_lo) / kAzBin) + 1,
                     -std::numeric_limits<float>::infinity());
  const auto binOf = [&](std::size_t k, double d) {
    return std::min(top_el[k].size() - 1,
                    static_cast<std::size_t>(std::max(0.0, (d - vehicles[k].az_lo) / kAzBin)));
  };
  for (const Column& c : columns) {
    float& t = top_el[c.k][binOf(c.k, c.d)];
    t = std::max(t, c.el);
  }
  // The stripes' points levelled once: horizontal range, height, azimuth.
  std::vector<Eigen::Vector3d> polar(stripe_points.size());
  for (std::size_t j = 0; j < stripe_points.size(); ++j) {
    const Eigen::Vector3d q = R * points[stripe_points[j]].xyz().cast<double>();
    polar[j] = {std::hypot(q.x(), q.y()), q.z(), std::atan2(q.y(), q.x())};
  }
  // Per stripe (its root's entry in `stripe_of`): its azimuths relative to its first return's,
  // its ranges, and its levelled box (z: its lowest and highest return).
  struct Stripe {
    uint32_t root;
    double az0, az_lo = 0, az_hi = 0, r_lo = 1e30, r_hi = 0;
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = Eigen::Vector3d::Constant(-1e30);
  };
  std::vector<Stripe> stripes;
  std::vector<int32_t> stripe_of(cc.voxels.size(), -1);
  for (std::size_t j = 0; j < stripe_points.size(); ++j) {
    const uint32_t r = rootOf(stripe_points[j]);
    if (stripe_of[r] < 0) {
      stripe_of[r] = static_cast<int32_t>(stripes.size());
      stripes.push_back({r, polar[j].z()});
    }
    Stripe& x = stripes[static_cast<std::size_t>(stripe_of[r])];
    const double d = relative(polar[j].z(), x.az0);
    x.az_lo = std::min(x.az_lo, d);
    x.az_hi = std::max(x.az_hi, d);
    x.r_lo = std::min(x.r_lo, polar[j].x());
    x.r_hi = std::max(x.r_hi, polar[j].x());
    const Eigen::Vector3d q(polar[j].x() * std::cos(polar[j].z()),
                            polar[j].x() * std::sin(polar[j].z()), polar[j].y());
    x.lo = x.lo.cwiseMin(q);
    x.hi = x.hi.cwiseMax(q);
  }
  const auto stripeOf = [&](uint32_t r) -> const Stripe& {
    return stripes[static_cast<std::size_t>(stripe_of[r])];
  };
  // A stripe is a roof where every point of it lies in one vehicle's shadow. One on its faces
  // (its lowest ring's slice, or a partly flagged one joined to neither) is a part of it: the
  // vehicle reaches that low or high for the next one (a sparse lidar's car 19 m off in three
  // slices: the top one moving whole, the middle one 48 of 73, the lowest 7 of 67).
  std::vector<uint32_t> inside(cc.voxels.size(), 0), on_faces(cc.voxels.size(), 0),
      under_it(cc.voxels.size(), 0);
  std::vector<uint8_t> taken(cc.voxels.size(), 0);
  // Whether a stripe under a vehicle lies within `step` of the road: the median height of the
  // ground returns before it and under it (its azimuths and a voxel, from 3 m nearer to a voxel
  // beyond), at least 5 of them (once a stripe, on first use). A face reaching the road has its
  // lowest ring within a ring step of it; a hedge under a tree's crown does not.
  constexpr double kUnknown = -std::numeric_limits<double>::infinity();
  std::vector<double> road_at(cc.voxels.size(), kUnknown);  // NaN: too few ground returns
  std::vector<double> road;
  const auto lowEnough = [&](uint32_t r, double step) {
    const Stripe& x = stripeOf(r);
    if (road_at[r] != kUnknown) return x.hi.z() <= road_at[r] + step;
    const double margin = p.voxel / x.r_lo;
    road.clear();
    for (uint32_t i = 0; i < points.size(); ++i) {
      if (i >= ground.size() || !ground[i]) continue;
      const Eigen::Vector3d q = R * points[i].xyz().cast<double>();
      const double range = std::hypot(q.x(), q.y());
      if (range < x.r_lo - 3.0 || range > x.r_hi + p.voxel) continue;
      const double d = relative(std::atan2(q.y(), q.x()), x.az0);
      if (d >= x.az_lo - margin && d <= x.az_hi + margin) road.push_back(q.z());
    }
    road_at[r] = road.size() >= 5 ? median(road) : std::numeric_limits<double>::quiet_NaN();
    return x.hi.z() <= road_at[r] + step;  // false where NaN
  };
  for (std::size_t k = 0; k < vehicles.size(); ++k) {
    Vehicle v = vehicles[k];
    const double step = kRingReach * v.r_hi * p.ring_gap;  // a ring step at its far end
    // A walker has no roof: the ring over his head lands on what stands behind him (a wall's
    // ring 0.6 m over the head of a walker along it, 1.4 m of it in his shadow: `pedestrian_wall`
    // with a VLP-16, 8-11 false positives a scan). Only the slices on his faces are his. He
    // spans two rings or more; a vehicle's one-ring slice moving whole is a piece of something
    // that may have a roof (`curved_path`'s turning car with a VLP-16: 3 returns).
    const bool walker =
        (v.hi - v.lo).norm() <= p.narrow && v.top - v.bottom >= 0.5 * p.ring_gap * v.r_hi;
    const double reach = walker ? p.voxel : p.length;
    for (bool grew = true; grew;) {
      grew = false;
      const double z_hi = v.top + step, z_lo = v.top - p.voxel;
      std::fill(inside.begin(), inside.end(), 0u);
      std::fill(on_faces.begin(), on_faces.end(), 0u);
      std::fill(under_it.begin(), under_it.end(), 0u);
      for (std::size_t j = 0; j < stripe_points.size(); ++j) {
        const double range = polar[j].x(), z = polar[j].y(), az = polar[j].z();
        if (range < v.r_lo - p.voxel) continue;
        const bool faces = range <= v.r_hi + p.voxel;  // on its faces, not behind them
        const bool roof = range <= v.r_hi + reach && z >= z_lo && z <= z_hi;
        const bool under =
            !p.dense && faces && z < v.bottom && z >= v.bottom - step;  // a ring step under
        if (!roof && !under) continue;
        const double d = relative(az, mean[k]), margin = p.voxel / range;
        if (d < v.az_lo - margin || d > v.az_hi + margin) continue;
        // Behind its faces at a dense lidar, a roof: on the ring over its top there (within
        // half a ring step). A sparse lidar's vehicle is a few slices: a column's top is not
        // the ring under the stripe (kitti_highway at 16 rings: a car's slice 0.6 m behind its
        // far end, 1.5 degrees under the top return beside it, is the car's).
        if (p.dense && !faces && std::atan2(z, range) < top_el[k][binOf(k, d)] - 0.5 * p.ring_gap)
          continue;
        const uint32_t r = rootOf(stripe_points[j]);
        ++inside[r];
        on_faces[r] += faces;
        under_it[r] += !roof;
      }
      for (const uint32_t i : stripe_points) {
        const uint32_t r = rootOf(i);
        if (taken[r] || inside[r] < comp[r].n) continue;
        // Under it: its lowest ring, near the road, or a slice the test flags in part.
        if (under_it[r] > 0 && comp[r].moving < p.flagged * comp[r].n && !lowEnough(r, step))
          continue;
        taken[r] = 1;
        if (on_faces[r] < comp[r].n) continue;
        const Stripe& x = stripeOf(r);
        grew = grew || x.lo.z() < v.bottom || x.hi.z() > v.top;
        v.bottom = std::min(v.bottom, x.lo.z());
        v.top = std::max(v.top, x.hi.z());
      }
    }
  }
  // Stacks: where no slice of a vehicle moves whole, its slices each flagged in part lie one over
  // another, within 1.25 ring steps, over the same azimuths (half of the narrower one's) and
  // ranges (a voxel). Two or more of them, vehicle-sized together, are one object: each alone is
  // all its own foot to rule 2, which turned it but moved only its flagged returns (a VLP-16's
  // car turning 14 m off: three slices, 49 of 88 returns flagged in each).
  std::vector<const Stripe*> slices;
  for (const Stripe& x : stripes)
    if (!p.dense && !taken[x.root] && flaggedInPart(comp[x.root])) slices.push_back(&x);
  std::vector<std::size_t> stack(slices.size());
  for (std::size_t a = 0; a < slices.size(); ++a) stack[a] = a;
  const auto find = [&](std::size_t a) {
    while (stack[a] != a) a = stack[a] = stack[stack[a]];
    return a;
  };
  for (std::size_t a = 0; a < slices.size(); ++a)
    for (std::size_t b = a + 1; b < slices.size(); ++b) {
      const Stripe &A = *slices[a], &B = *slices[b];
      const double off = relative(B.az0, A.az0);
      const double overlap = std::min(A.az_hi, B.az_hi + off) - std::max(A.az_lo, B.az_lo + off);
      if (overlap < 0.5 * std::min(A.az_hi - A.az_lo, B.az_hi - B.az_lo)) continue;
      if (A.r_lo > B.r_hi + p.voxel || B.r_lo > A.r_hi + p.voxel) continue;
      const double gap = std::max(A.lo.z() - B.hi.z(), B.lo.z() - A.hi.z());
      if (gap > kRingReach * std::max(A.r_hi, B.r_hi) * p.ring_gap) continue;
      const std::size_t ra = find(a), rb = find(b);
      stack[std::max(ra, rb)] = std::min(ra, rb);
    }
  std::vector<uint32_t> count(slices.size(), 0);
  std::vector<Eigen::Vector3d> lo(slices.size(), Eigen::Vector3d::Constant(1e30)),
      hi(slices.size(), Eigen::Vector3d::Constant(-1e30));
  for (std::size_t a = 0; a < slices.size(); ++a) {
    const std::size_t g = find(a);
    ++count[g];
    lo[g] = lo[g].cwiseMin(slices[a]->lo);
    hi[g] = hi[g].cwiseMax(slices[a]->hi);
  }
  for (std::size_t a = 0; a < slices.size(); ++a) {
    const std::size_t g = find(a);
    if (count[g] >= 2 && (hi[g] - lo[g]).head<2>().norm() <= p.max_length &&
        hi[g].z() - lo[g].z() <= p.max_height)
      taken[slices[a]->root] = 1;
  }
  for (const uint32_t i : stripe_points)
    if (taken[rootOf(i)] && !moving[i]) out.push_back(i);
  return out;
}

}  // namespace cleanmap
