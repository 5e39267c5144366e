// SPDX-License-Identifier: BSD-3-Clause
// Simulated HDL-64E and camera (issue #4): ray casting World at the sweep's instants.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "cleanmap/core/parallel.h"
#include "cleanmap/sim/world.h"

namespace cleanmap::sim {
namespace {

constexpr int kSlices = 72;             // 5 deg azimuth slices: culling unit and, with
                                        // sweep motion, the time step (1.4 ms)
constexpr double kIgnoreBeyond = 50.0;  // m horizontal: ignore label, as in ../shared/data

uint64_t splitmix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
double uniform(uint64_t h) {
  return (static_cast<double>(h >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

double wrapPi(double a) {
  while (a > M_PI) a -= 2 * M_PI;
  while (a < -M_PI) a += 2 * M_PI;
  return a;
}

// Solids whose xy bounding circle, seen from the sensor, overlaps azimuths [a_lo, a_hi]
// (sensor frame), inflated by `margin` metres.
std::vector<int> cull(const World& w, const Eigen::Isometry3d& pose, double a_lo, double a_hi,
                      double margin) {
  std::vector<int> out;
  const Eigen::Isometry3d inv = pose.inverse();
  const double mid = 0.5 * (a_lo + a_hi), half = 0.5 * (a_hi - a_lo);
  for (int i = 0; i < static_cast<int>(w.solids().size()); ++i) {
    const Solid& s = w.solids()[i];
    const Eigen::Vector3d c = inv * s.center;
    const double d = c.head<2>().norm(), r = s.bound + margin;
    if (d <= r) {
      out.push_back(i);
      continue;
    }
    const double spread = std::asin(std::min(1.0, r / d));
    if (std::abs(wrapPi(std::atan2(c.y(), c.x()) - mid)) <= half + spread) out.push_back(i);
  }
  return out;
}

}  // namespace

namespace {
// egoPose of frame k plus a seeded random walk on x and y of `drift` per metre travelled; `salt`
// keeps the walks of the written poses and of the odometry apart.
Eigen::Isometry3d driftedPose(const Scenario& sc, int k, double drift, uint64_t salt) {
  Eigen::Isometry3d T = egoPose(sc, k / sc.rate_hz);
  if (drift <= 0) return T;
  const double step = drift * sc.ego_speed / sc.rate_hz;  // sigma per frame, m
  Eigen::Vector2d e = Eigen::Vector2d::Zero();
  for (int j = 1; j <= k; ++j)
    for (int a = 0; a < 2; ++a) {
      const uint64_t h =
          splitmix(sc.seed * 0x9E3779B97F4A7C15ull ^ (salt << 40) ^ (uint64_t(j) * 2 + a));
      const double g = std::sqrt(-2 * std::log(uniform(splitmix(h ^ 1)))) *
                       std::cos(2 * M_PI * uniform(splitmix(h ^ 2)));
      e[a] += step * g;
    }
  T.translation().head<2>() += e;
  return T;
}
}  // namespace

Eigen::Isometry3d reportedPose(const Scenario& sc, int k) {
  return driftedPose(sc, k, sc.ego_pose_drift, 0xD1F7);
}

std::optional<Eigen::Isometry3d> odometryPose(const Scenario& sc, int k) {
  if (sc.ego_odometry < 0) return std::nullopt;
  return driftedPose(sc, k, sc.ego_odometry, 0x0D0E);
}

SimScan simulateScan(const Scenario& sc, int k, int threads) {
  const auto& elev = sc.sensor.elevations;
  const int rings = static_cast<int>(elev.size());
  const int ncol =
      std::max(kSlices, static_cast<int>(std::lround(360.0 / sc.sensor.azimuth_step_deg)));
  const double t_k = k / sc.rate_hz, sweep = 1.0 / sc.rate_hz;
  SimScan out;
  out.time = t_k;
  out.pose = egoPose(sc, t_k);
  out.reported_pose = reportedPose(sc, k);
  const std::optional<World> shared =
      sc.sensor.sweep_motion ? std::nullopt : std::optional<World>(World(sc, t_k));

  struct Part {
    std::vector<PointXYZI> pts;
    Labels labels;
    std::vector<Surface> surf;
    std::vector<int> solid;
    std::vector<float> time;
  };
  std::vector<Part> parts(kSlices);
  parallelFor(
      kSlices, threads,
      [&](std::size_t slice) {  // one slice per chunk
        const int sl = static_cast<int>(slice);
        const int c0 = sl * ncol / kSlices, c1 = (sl + 1) * ncol / kSlices;
        // Columns sweep clockwise from behind the car (azimuth +pi) through the front (0).
        const auto az = [&](int c) { return M_PI - 2 * M_PI * (c + 0.5) / ncol; };
        const double t =
            sc.sensor.sweep_motion ? t_k + ((c0 + c1) * 0.5 / ncol - 0.5) * sweep : t_k;
        const std::optional<World> own = shared ? std::nullopt : std::optional<World>(World(sc, t));
        const World& w = shared ? *shared : *own;
        const Eigen::Isometry3d pose = shared ? out.pose : egoPose(sc, t);
        const auto dt = static_cast<float>(t - t_k);  // the slice's capture time
        const std::vector<int> cand = cull(w, pose, az(c1 - 1) - 1e-3, az(c0) + 1e-3, 0.1);
        Part& p = parts[sl];
        p.pts.reserve(static_cast<std::size_t>((c1 - c0) * rings));
        Hit hit;
        for (int c = c0; c < c1; ++c) {
          const double a = az(c), ca = std::cos(a), sa = std::sin(a);
          for (int r = 0; r < rings; ++r) {
            const Eigen::Vector3d dl(std::cos(elev[r]) * ca, std::cos(elev[r]) * sa,
                                     std::sin(elev[r]));
            const Eigen::Vector3d dw = pose.linear() * dl;
            if (!w.intersect(pose.translation(), dw, sc.sensor.max_range, hit, &cand)) continue;
            // Rings beyond the 64th draw from their own stream (the 64-ring ids stay as they were).
            const uint64_t id =
                (static_cast<uint64_t>(k) * 64 + static_cast<uint64_t>(r % 64)) * 100000 +
                static_cast<uint64_t>(c) + (static_cast<uint64_t>(r / 64) << 56);
            const uint64_t h = splitmix(sc.seed * 0x2545F4914F6CDD1Dull ^ id);
            if (uniform(splitmix(h ^ 1)) < sc.sensor.dropout) continue;
            const double g = std::sqrt(-2 * std::log(uniform(splitmix(h ^ 2)))) *
                             std::cos(2 * M_PI * uniform(splitmix(h ^ 3)));
            const double range = hit.t + sc.sensor.range_noise * g;
            if (range < sc.sensor.min_range || range > sc.sensor.max_range) continue;
            const Eigen::Vector3d q = dl * range;
            const double refl = hit.surface == Surface::kGround  ? 0.25
                                : hit.surface == Surface::kMover ? 0.6
                                                                 : 0.45;
            p.pts.push_back({float(q.x()), float(q.y()), float(q.z()),
                             float(refl * std::abs(hit.normal.dot(dw)))});
            uint32_t label = 9;
            if (hit.surface == Surface::kMover) {
              const int m = w.solids()[hit.object].motion;
              label = m > 0 ? 251 : (m == 0 ? 9 : 0);
            }
            if (q.head<2>().norm() > kIgnoreBeyond) label = 0;
            p.labels.push_back(label);
            p.surf.push_back(hit.surface);
            p.solid.push_back(hit.object);
            if (sc.sensor.sweep_motion) p.time.push_back(dt);
          }
        }
      },
      1);
  for (auto& p : parts) {
    out.points.insert(out.points.end(), p.pts.begin(), p.pts.end());
    out.labels.insert(out.labels.end(), p.labels.begin(), p.labels.end());
    out.surface.insert(out.surface.end(), p.surf.begin(), p.surf.end());
    out.solid.insert(out.solid.end(), p.solid.begin(), p.solid.end());
    out.point_time.insert(out.point_time.end(), p.time.begin(), p.time.end());
  }
  return out;
}

PinholeCamera kittiCamera() {
  // KITTI raw 2011_09_26 calibration (rectified P2; velodyne -> rectified camera 0).
  PinholeCamera c;
  c.name = "image_2";
  c.width = 1242;
  c.height = 375;
  c.P << 721.5377, 0, 609.5593, 44.85728, 0, 721.5377, 172.854, 0.2163791, 0, 0, 1, 0.002745884;
  Eigen::Matrix3d R;
  R << 7.533745e-03, -9.999714e-01, -6.166020e-04, 1.480249e-02, 7.280733e-04, -9.998902e-01,
      9.998621e-01, 7.523790e-03, 1.480755e-02;
  // Re-orthonormalise so the transform is a true isometry (the published one is to ~1e-6).
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  c.T_cam_lidar.linear() = svd.matrixU() * svd.matrixV().transpose();
  c.T_cam_lidar.translation() = Eigen::Vector3d(-4.069766e-03, -7.631618e-02, -2.717806e-01);
  return c;
}

namespace {

Eigen::Vector3f shade(const World& w, const Hit& h) {
  Eigen::Vector3f base;
  if (h.object < 0) {
    // Asphalt / pavement: fine procedural grain, lane marks on the road.
    const double n = uniform(splitmix(uint64_t(int64_t(std::floor(h.uv.x() * 10)) * 73856093) ^
                                      uint64_t(int64_t(std::floor(h.uv.y() * 10)) * 19349663)));
    base = Eigen::Vector3f::Constant(float(0.30 + 0.12 * n));
    if (h.surface == Surface::kGround && std::abs(h.uv.y()) < 0.08 &&
        std::fmod(std::abs(h.uv.x()), 6.0) < 3.0)
      base = Eigen::Vector3f::Constant(0.9f);
    if (h.object == -2) base = {0.55f, 0.5f, 0.45f};
  } else {
    const Solid& s = w.solids()[h.object];
    base = s.colour;
    if (s.texture == Texture::kChecker) {
      const int cu = int(std::floor(h.uv.x() / 0.25)), cv = int(std::floor(h.uv.y() / 0.25));
      const double n = uniform(splitmix(uint64_t(cu * 7919 + cv * 104729 + h.object * 31)));
      base *= float(((cu + cv) & 1 ? 0.55 : 1.0) * (0.8 + 0.4 * n));
    }
  }
  const Eigen::Vector3d light = Eigen::Vector3d(0.4, 0.3, 0.87).normalized();
  const double lambert = 0.45 + 0.55 * std::max(0.0, h.normal.dot(light));
  return (base * float(lambert)).cwiseMin(1.0f);
}

}  // namespace

cv::Mat renderImage(const Scenario& sc, int k, const PinholeCamera& cam, int threads,
                    bool cull_solids) {
  const double t_k = k / sc.rate_hz;
  const World w(sc, t_k);
  const Eigen::Isometry3d T_world_lidar = egoPose(sc, t_k);
  const Eigen::Isometry3d T_opt_lidar = cam.opticalFromLidar();
  const Eigen::Matrix3d R_world_opt = T_world_lidar.linear() * T_opt_lidar.linear().inverse();
  const Eigen::Vector3d origin = T_world_lidar * (T_opt_lidar.inverse() * Eigen::Vector3d::Zero());
  const Eigen::Matrix3d Kinv = cam.K().inverse();
  // Solids culled per band of columns: a band's rays span, in the world's xy plane, the azimuths
  // of its four corner rays (a convex cone narrower than pi), and a ray hits a solid only where
  // its azimuth from the camera's centre meets the solid's upright bounding cylinder. Each band
  // keeps, in index order, every solid a ray of it can hit: the same hits, the same image.
  constexpr int kBand = 32;
  const int bands = (cam.width + kBand - 1) / kBand;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  // upright, at the centre
  T_world_cam.translation() = origin;
  std::vector<std::vector<int>> band_solids(static_cast<std::size_t>(bands));
  for (int b = 0; b < bands; ++b) {
    std::optional<double> first;
    double lo = 0, hi = 0;  // relative to the first corner's azimuth
    for (const double u : {double(b * kBand), double(std::min(cam.width, (b + 1) * kBand))})
      for (const double v : {0.0, double(cam.height)}) {
        const Eigen::Vector3d d = R_world_opt * (Kinv * Eigen::Vector3d(u, v, 1.0));
        const double a = std::atan2(d.y(), d.x());
        if (!first) first = a;
        const double r = wrapPi(a - *first);
        lo = std::min(lo, r), hi = std::max(hi, r);
      }
    if (cull_solids && hi - lo < 0.9 * M_PI)  // else it may look straight up or down: all
      band_solids[b] = cull(w, T_world_cam, *first + lo - 1e-3, *first + hi + 1e-3, 0.1);
    else
      for (int i = 0; i < static_cast<int>(w.solids().size()); ++i) band_solids[b].push_back(i);
  }
  cv::Mat img(cam.height, cam.width, CV_8UC3);
  parallelFor(
      static_cast<std::size_t>(cam.height), threads,
      [&](std::size_t row_index) {
        const int v = static_cast<int>(row_index);
        Hit hit;
        auto* row = img.ptr<cv::Vec3b>(v);
        for (int u = 0; u < cam.width; ++u) {
          const Eigen::Vector3d d =
              (R_world_opt * (Kinv * Eigen::Vector3d(u + 0.5, v + 0.5, 1.0))).normalized();
          Eigen::Vector3f c;
          if (w.intersect(origin, d, 300.0, hit, &band_solids[u / kBand])) {
            c = shade(w, hit);
            const float fog = float(std::min(1.0, hit.t / 300.0));
            c = (1 - fog) * c + fog * Eigen::Vector3f(0.85f, 0.8f, 0.75f);
          } else {
            const float up = float(std::clamp(d.z() * 3.0, 0.0, 1.0));
            c = Eigen::Vector3f(0.85f, 0.87f, 0.9f) * (1 - up) +
                Eigen::Vector3f(0.45f, 0.65f, 0.95f) * up;  // sky (RGB)
          }
          row[u] = cv::Vec3b(uchar(255 * c.z()), uchar(255 * c.y()), uchar(255 * c.x()));
        }
      },
      8);
  return img;
}

Frame frameOf(SimScan&& s, int k) {
  Frame f;
  f.index = static_cast<std::size_t>(k);
  char stem[16];
  std::snprintf(stem, sizeof stem, "%06d", k);
  f.stem = stem;
  f.scan.original_size = s.points.size();
  f.scan.points = std::move(s.points);
  f.scan.point_time = std::move(s.point_time);
  f.scan.pose = s.reported_pose;
  f.scan.has_pose = true;
  f.scan.timestamp = s.time;
  return f;
}

}  // namespace cleanmap::sim
