// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/sim/world.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cleanmap::sim {
namespace {

constexpr double kEps = 1e-9;

// Ray / plane n.x = d; returns t or +inf.
double planeT(const Eigen::Vector3d& o, const Eigen::Vector3d& dir, const Eigen::Vector3d& n,
              double d) {
  const double den = n.dot(dir);
  if (std::abs(den) < kEps) return std::numeric_limits<double>::infinity();
  const double t = (d - n.dot(o)) / den;
  return t > 1e-6 ? t : std::numeric_limits<double>::infinity();
}

// Distance covered y seconds after pulling away from rest at `a` up to speed `v` (y >= 0).
double rampDistance(double v, double a, double y) {
  const double ramp = v / a;
  return y <= ramp ? 0.5 * a * y * y : 0.5 * v * ramp + v * (y - ramp);
}

// Distance covered by time t within one stretch of motion [s, e] (e may be +inf): pulls away at
// s, brakes to stand at e, at `a` up to speed `v`. The profile min(v, a(t - s), a(e - t)) is
// symmetric, so its rise and its fall meet at the middle.
double stretchDistance(double v, double a, double s, double e, double t) {
  if (t <= s || e <= s) return 0.0;
  t = std::min(t, e);
  const double mid = std::isinf(e) ? e : 0.5 * (s + e);
  if (t <= mid) return rampDistance(v, a, t - s);
  return rampDistance(v, a, mid - s) + rampDistance(v, a, e - mid) - rampDistance(v, a, e - t);
}

}  // namespace

double moverArc(const MoverSpec& m, double t) {
  const double inf = std::numeric_limits<double>::infinity();
  // Stretches of motion: [start, stop_from] and [stop_to, inf), or [start, inf).
  double a0 = inf, b0 = m.start;
  if (m.stop) a0 = std::max(m.stop->first, m.start), b0 = std::max(m.stop->second, m.start);
  if (m.accel <= 0) {
    const double moving = std::max(0.0, t - m.start) - std::max(0.0, std::min(t, b0) - a0);
    return m.speed * std::max(0.0, moving);
  }
  // A mover that waits pulls away from rest at `start`; one that does not (start = 0) is at speed
  // from the first frame, as if it had pulled away v / a earlier.
  const double from = m.start > 0 ? m.start : -m.speed / m.accel;
  const double first = stretchDistance(m.speed, m.accel, from, a0, std::max(t, m.start)) -
                       stretchDistance(m.speed, m.accel, from, a0, m.start);
  return m.stop ? first + stretchDistance(m.speed, m.accel, b0, inf, t) : first;
}

Eigen::Vector3d alongPath(const std::vector<Eigen::Vector2d>& path, double s) {
  // Before the start (the first sweep of a sensor moving during it, t < 0): on along the first
  // segment, so that the motion is steady from the first instant.
  if (s < 0 && path.size() >= 2 && (path[1] - path[0]).norm() > 0) {
    const Eigen::Vector2d d = (path[1] - path[0]).normalized();
    const Eigen::Vector2d p = path[0] + d * s;
    return {p.x(), p.y(), std::atan2(d.y(), d.x())};
  }
  s = std::max(0.0, s);
  for (std::size_t i = 1; i < path.size(); ++i) {
    const Eigen::Vector2d d = path[i] - path[i - 1];
    const double len = d.norm();
    if (s <= len || i + 1 == path.size()) {
      const Eigen::Vector2d p = path[i - 1] + d * std::min(1.0, s / len);
      return {p.x(), p.y(), std::atan2(d.y(), d.x())};
    }
    s -= len;
  }
  return {path[0].x(), path[0].y(), 0.0};
}

const std::vector<double>& hdl64Elevations() {
  static const std::vector<double> e = ringElevations(SensorModel::kHdl64);
  return e;
}

World::World(const Scenario& sc, double t) : g_(sc.ground) {
  int tracked = 0;
  for (const auto& b : sc.boxes) {
    Solid s;
    s.kind = Solid::kBox;
    s.half = 0.5 * b.size;
    s.center = {b.center.x(), b.center.y(),
                groundHeight(b.center.x(), b.center.y()) + b.lift + s.half.z()};
    s.yaw = b.yaw;
    s.surface = Surface::kStatic;
    s.texture = b.texture;
    s.colour = b.colour;
    s.name = b.name;
    s.cls = b.cls;
    if (b.tracked) s.tracked_id = ++tracked;
    solids_.push_back(s);
  }
  for (const auto& c : sc.cylinders) {
    Solid s;
    s.kind = Solid::kCylinder;
    s.center = {c.center.x(), c.center.y(), groundHeight(c.center.x(), c.center.y()) - 0.05};
    s.radius = c.radius;
    s.height = c.height + 0.05;
    s.surface = Surface::kStatic;
    s.texture = Texture::kFlat;
    s.colour = c.colour;
    s.name = c.name;
    s.cls = c.cls;
    solids_.push_back(s);
  }
  for (const auto& m : sc.movers) {
    const Eigen::Vector3d p = alongPath(m.path, moverArc(m, t));
    Solid s;
    s.kind = Solid::kBox;
    s.half = 0.5 * m.size;
    s.center = {p.x(), p.y(), groundHeight(p.x(), p.y()) + s.half.z() + 0.02};
    s.yaw = p.z();
    s.surface = Surface::kMover;
    s.texture = m.texture;
    s.colour = m.colour;
    s.name = m.name;
    s.cls = m.cls;
    s.tracked_id = ++tracked;
    // Motion truth over +-0.5 s (the data's +-5 scans at 10 Hz).
    const double dist = (alongPath(m.path, moverArc(m, t + 0.5)).head<2>() -
                         alongPath(m.path, moverArc(m, t - 0.5)).head<2>())
                            .norm();
    s.motion = dist > 0.5 ? 1 : (dist < 0.2 ? 0 : -1);
    solids_.push_back(s);
  }
  for (auto& s : solids_) {
    s.c = std::cos(s.yaw);
    s.s = std::sin(s.yaw);
    s.bound = s.kind == Solid::kBox ? s.half.head<2>().norm() : s.radius;
  }
}

double World::groundHeight(double x, double y) const {
  return sim::groundHeight(g_, x, y);
}

double groundHeight(const GroundSpec& g_, double x, double y) {
  double z = g_.slope * x;
  if (std::abs(y) > g_.road_half_width) return z + g_.curb_height;
  if (g_.ramp) {
    const auto& r = *g_.ramp;
    if (x >= r[0] && x <= r[2] && y >= r[3] && y <= r[4])
      z += x < r[1] ? r[5] * (x - r[0]) / (r[1] - r[0]) : r[5];
  }
  return z;
}

bool World::intersectGround(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_t,
                            Hit& hit) const {
  bool found = false;
  const double W = g_.road_half_width, slope = g_.slope;
  auto accept = [&](double t, Eigen::Vector3d n, Surface surf, const Eigen::Vector2d& uv) {
    if (t <= max_t && t < hit.t) {
      hit.t = t;
      if (n.dot(d) > 0) n = -n;
      hit.normal = n.normalized();
      hit.surface = surf;
      hit.object = -1;
      hit.uv = uv;
      found = true;
    }
  };
  const Eigen::Vector3d n_road(-slope, 0, 1);  // plane z = slope x + c
  // Road plane (c = 0), outside the ramp.
  {
    const double t = planeT(o, d, n_road, 0.0);
    if (std::isfinite(t)) {
      const Eigen::Vector3d q = o + t * d;
      bool on_ramp = false;
      if (g_.ramp) {
        const auto& r = *g_.ramp;
        on_ramp = q.x() >= r[0] && q.x() <= r[2] && q.y() >= r[3] && q.y() <= r[4];
      }
      if (std::abs(q.y()) <= W && !on_ramp) accept(t, n_road, Surface::kGround, q.head<2>());
    }
  }
  // Sidewalks / terrain beyond the curbs.
  {
    const double t = planeT(o, d, n_road, g_.curb_height);
    if (std::isfinite(t)) {
      const Eigen::Vector3d q = o + t * d;
      if (std::abs(q.y()) > W) accept(t, n_road, Surface::kGround, q.head<2>());
    }
  }
  // Curb faces y = +-W between the road and the sidewalk.
  if (g_.curb_height > 0)
    for (const double side : {-1.0, 1.0}) {
      const double t = planeT(o, d, Eigen::Vector3d(0, 1, 0), side * W);
      if (!std::isfinite(t)) continue;
      const Eigen::Vector3d q = o + t * d;
      const double base = slope * q.x();
      if (q.z() >= base && q.z() <= base + g_.curb_height)
        accept(t, Eigen::Vector3d(0, -side, 0), Surface::kCurb, {q.x(), q.z()});
    }
  if (g_.ramp) {
    const auto& r = *g_.ramp;
    const double x0 = r[0], x1 = r[1], x2 = r[2], y0 = r[3], y1 = r[4], h = r[5];
    const double k = h / (x1 - x0);
    // Ramp slope: z = slope x + k (x - x0).
    const Eigen::Vector3d n_up(-(slope + k), 0, 1);
    double t = planeT(o, d, n_up, -k * x0);
    if (std::isfinite(t)) {
      const Eigen::Vector3d q = o + t * d;
      if (q.x() >= x0 && q.x() <= x1 && q.y() >= y0 && q.y() <= y1)
        accept(t, n_up, Surface::kGround, q.head<2>());
    }
    t = planeT(o, d, n_road, h);  // plateau
    if (std::isfinite(t)) {
      const Eigen::Vector3d q = o + t * d;
      if (q.x() > x1 && q.x() <= x2 && q.y() >= y0 && q.y() <= y1)
        accept(t, n_road, Surface::kGround, q.head<2>());
    }
    // Sides and end: vertical step faces of the ground, like curbs.
    for (const double yy : {y0, y1}) {
      t = planeT(o, d, Eigen::Vector3d(0, 1, 0), yy);
      if (!std::isfinite(t)) continue;
      const Eigen::Vector3d q = o + t * d;
      if (q.x() < x0 || q.x() > x2) continue;
      const double base = slope * q.x(), top = base + (q.x() < x1 ? k * (q.x() - x0) : h);
      if (q.z() >= base && q.z() <= top) {
        const double before = hit.t;
        accept(t, Eigen::Vector3d(0, 1, 0), Surface::kCurb, {q.x(), q.z()});
        if (hit.t < before) hit.object = -2;
      }
    }
    t = planeT(o, d, Eigen::Vector3d(1, 0, 0), x2);
    if (std::isfinite(t)) {
      const Eigen::Vector3d q = o + t * d;
      const double base = slope * q.x();
      if (q.y() >= y0 && q.y() <= y1 && q.z() >= base && q.z() <= base + h) {
        const double before = hit.t;
        accept(t, Eigen::Vector3d(1, 0, 0), Surface::kCurb, {q.y(), q.z()});
        if (hit.t < before) hit.object = -2;
      }
    }
  }
  return found;
}

bool World::intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_t, Hit& hit,
                      const std::vector<int>* only) const {
  hit = Hit{};
  hit.t = std::numeric_limits<double>::infinity();
  bool found = intersectGround(o, d, max_t, hit);
  auto test = [&](int idx) {
    const Solid& s = solids_[idx];
    // Into the solid's frame (rotation about z by -yaw).
    const Eigen::Vector3d rel = o - s.center;
    const Eigen::Vector3d lo(s.c * rel.x() + s.s * rel.y(), -s.s * rel.x() + s.c * rel.y(),
                             rel.z());
    const Eigen::Vector3d ld(s.c * d.x() + s.s * d.y(), -s.s * d.x() + s.c * d.y(), d.z());
    double t_hit = std::numeric_limits<double>::infinity();
    Eigen::Vector3d n_local = Eigen::Vector3d::UnitZ();
    Eigen::Vector2d uv(0, 0);
    if (s.kind == Solid::kBox) {
      double tmin = -std::numeric_limits<double>::infinity(),
             tmax = std::numeric_limits<double>::infinity();
      int axis = -1;
      double sign = 1;
      for (int a = 0; a < 3; ++a) {
        if (std::abs(ld[a]) < kEps) {
          if (std::abs(lo[a]) > s.half[a]) return;
          continue;
        }
        double t1 = (-s.half[a] - lo[a]) / ld[a], t2 = (s.half[a] - lo[a]) / ld[a];
        double sg = -1;
        if (t1 > t2) std::swap(t1, t2), sg = 1;
        if (t1 > tmin) tmin = t1, axis = a, sign = sg;
        tmax = std::min(tmax, t2);
        if (tmin > tmax) return;
      }
      if (tmin <= 1e-6 || axis < 0) return;  // origin inside, or behind
      t_hit = tmin;
      n_local = Eigen::Vector3d::Zero();
      n_local[axis] = sign;
      const Eigen::Vector3d q = lo + tmin * ld;
      uv = axis == 2 ? Eigen::Vector2d(q.x(), q.y())
                     : Eigen::Vector2d(axis == 0 ? q.y() : q.x(), q.z());
    } else {
      const double a = ld.x() * ld.x() + ld.y() * ld.y();
      if (a > kEps) {
        const double b = lo.x() * ld.x() + lo.y() * ld.y();
        const double c = lo.x() * lo.x() + lo.y() * lo.y() - s.radius * s.radius;
        const double disc = b * b - a * c;
        if (disc >= 0) {
          const double t = (-b - std::sqrt(disc)) / a;
          const double z = lo.z() + t * ld.z();
          if (t > 1e-6 && z >= 0 && z <= s.height) {
            t_hit = t;
            const Eigen::Vector3d q = lo + t * ld;
            n_local = Eigen::Vector3d(q.x(), q.y(), 0).normalized();
            uv = {std::atan2(q.y(), q.x()) * s.radius, q.z()};
          }
        }
      }
      if (std::abs(ld.z()) > kEps) {  // top cap
        const double t = (s.height - lo.z()) / ld.z();
        const Eigen::Vector3d q = lo + t * ld;
        if (t > 1e-6 && t < t_hit && q.head<2>().squaredNorm() <= s.radius * s.radius) {
          t_hit = t;
          n_local = Eigen::Vector3d::UnitZ();
          uv = q.head<2>();
        }
      }
    }
    if (t_hit <= max_t && t_hit < hit.t) {
      hit.t = t_hit;
      hit.normal = {s.c * n_local.x() - s.s * n_local.y(), s.s * n_local.x() + s.c * n_local.y(),
                    n_local.z()};
      hit.surface = s.surface;
      hit.object = idx;
      hit.uv = uv;
      found = true;
    }
  };
  if (only)
    for (int i : *only) test(i);
  else
    for (int i = 0; i < static_cast<int>(solids_.size()); ++i) test(i);
  return found;
}

Eigen::Isometry3d egoPose(const Scenario& sc, double t) {
  const Eigen::Vector3d p = alongPath(sc.ego_path, sc.ego_speed * t);
  auto height = [&](double x, double y) { return groundHeight(sc.ground, x, y); };
  const double h = height(p.x(), p.y());
  // Pitch from the road grade along the heading (over the car's 2.7 m wheelbase).
  const Eigen::Vector2d dir(std::cos(p.z()), std::sin(p.z()));
  const double ahead = height(p.x() + 1.35 * dir.x(), p.y() + 1.35 * dir.y());
  const double behind = height(p.x() - 1.35 * dir.x(), p.y() - 1.35 * dir.y());
  const double pitch = -std::atan2(ahead - behind, 2.7);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(p.x(), p.y(), h + sc.sensor.height);
  T.linear() = (Eigen::AngleAxisd(p.z(), Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()))
                   .toRotationMatrix();
  return T;
}

}  // namespace cleanmap::sim
