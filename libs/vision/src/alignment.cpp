// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/vision/alignment.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

namespace cleanmap::vision {
namespace {

constexpr int kCoarsest = 3, kFinest = 1, kIterations = 10;

// Bilinear intensity at (u, v), pixel centres at integer coordinates; false outside the image
// with a one-pixel border (the gradient's central differences stay inside).
bool sample(const cv::Mat& g, double u, double v, float& out) {
  if (!(u >= 1 && v >= 1 && u < g.cols - 2 && v < g.rows - 2)) return false;
  const int x = static_cast<int>(u), y = static_cast<int>(v);
  const float a = static_cast<float>(u - x), b = static_cast<float>(v - y);
  const float* r0 = g.ptr<float>(y) + x;
  const float* r1 = g.ptr<float>(y + 1) + x;
  out = (1 - b) * ((1 - a) * r0[0] + a * r0[1]) + b * ((1 - a) * r1[0] + a * r1[1]);
  return true;
}

struct RefPoint {
  Eigen::Vector3d world;
  float intensity[kCoarsest + 1];
};

// The residuals of the points at level `level` with the correction c applied to other's optical
// frame; with_jacobian: the normal equations of the 6-DoF update (translation, rotation) too.
struct Accumulated {
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
  double error = 0, weights = 0, residual_sum = 0;
  int n = 0;
};
Accumulated accumulate(const std::vector<RefPoint>& pts, const CameraView& other, int level,
                       const Eigen::Isometry3d& c, double bias, const AlignParams& ap,
                       bool with_jacobian) {
  const double huber = ap.huber;
  Accumulated a;
  const cv::Mat& g = other.grey[static_cast<std::size_t>(level)];
  const double s = std::ldexp(1.0, -level);
  const double fx = other.fx * s, fy = other.fy * s, cx = other.cx * s, cy = other.cy * s;
  const Eigen::Isometry3d T = c * other.optical_from_world;
  for (const RefPoint& p : pts) {
    const Eigen::Vector3d X = T * p.world;
    if (X.z() <= 0.3) continue;
    const double iz = 1.0 / X.z();
    const double u = fx * X.x() * iz + cx, v = fy * X.y() * iz + cy;
    float I;
    if (!sample(g, u, v, I)) continue;
    // Hidden in other's view (a nearer lidar return of its own at the pixel): not compared.
    if (nearestReturn(other, Eigen::Vector2d(u / s, v / s)) < X.norm() - ap.occlusion) continue;
    const double r = double(I) - p.intensity[level] - bias;
    const double w = std::abs(r) <= huber ? 1.0 : huber / std::abs(r);
    a.error += w * r * r;
    a.weights += w;
    a.residual_sum += w * (r + bias);
    ++a.n;
    if (!with_jacobian) continue;
    float il, ir, iu, id;
    if (!sample(g, u - 1, v, il) || !sample(g, u + 1, v, ir) || !sample(g, u, v - 1, iu) ||
        !sample(g, u, v + 1, id))
      continue;
    const double gx = 0.5 * (ir - il), gy = 0.5 * (id - iu);
    // d(u, v)/dX, then dX/d(translation, rotation) = [I | -[X]x] (left perturbation).
    const Eigen::RowVector3d du(fx * iz, 0, -fx * X.x() * iz * iz);
    const Eigen::RowVector3d dv(0, fy * iz, -fy * X.y() * iz * iz);
    const Eigen::RowVector3d dI = gx * du + gy * dv;
    Eigen::Matrix<double, 1, 6> J;
    J.head<3>() = dI;
    J.tail<3>() = X.transpose().cross(dI);  // dI * (-[X]x) = X x dI
    a.H.noalias() += w * J.transpose() * J;
    a.g.noalias() += w * J.transpose() * r;
  }
  return a;
}

}  // namespace

CameraView corrected(const CameraView& v, const Eigen::Isometry3d& correction) {
  CameraView c = v;
  c.optical_from_world = correction * v.optical_from_world;
  c.centre = c.optical_from_world.inverse().translation();
  return c;
}

std::optional<Alignment> alignView(const CameraView& ref, const CameraView& other,
                                   const std::vector<Eigen::Vector3d>& static_world,
                                   const AlignParams& p) {
  if (ref.grey.size() <= kCoarsest || other.grey.size() <= kCoarsest) return std::nullopt;
  // Reference points: static returns that ref sees on texture (gradient at half resolution).
  std::vector<RefPoint> pts;
  const cv::Mat& g1 = ref.grey[kFinest];
  for (const Eigen::Vector3d& x : static_world) {
    const Eigen::Vector3d q = ref.optical_from_world * x;
    if (q.z() <= 0.3) continue;
    RefPoint rp{x, {}};
    bool ok = true;
    for (int l = kFinest; l <= kCoarsest && ok; ++l) {
      const double s = std::ldexp(1.0, -l);
      ok = sample(ref.grey[static_cast<std::size_t>(l)], (ref.fx * q.x() / q.z() + ref.cx) * s,
                  (ref.fy * q.y() / q.z() + ref.cy) * s, rp.intensity[l]);
    }
    if (!ok) continue;
    const double u = (ref.fx * q.x() / q.z() + ref.cx) * 0.5,
                 v = (ref.fy * q.y() / q.z() + ref.cy) * 0.5;
    float il, ir, iu, id;
    if (!sample(g1, u - 1, v, il) || !sample(g1, u + 1, v, ir) || !sample(g1, u, v - 1, iu) ||
        !sample(g1, u, v + 1, id))
      continue;
    if (std::hypot(0.5 * (ir - il), 0.5 * (id - iu)) < p.min_gradient) continue;
    pts.push_back(rp);
  }
  if (static_cast<int>(pts.size()) < p.min_points) return std::nullopt;
  if (static_cast<int>(pts.size()) > p.max_points) {  // evenly thinned, deterministic
    std::vector<RefPoint> thin;
    thin.reserve(static_cast<std::size_t>(p.max_points));
    for (int i = 0; i < p.max_points; ++i)
      thin.push_back(pts[static_cast<std::size_t>(i) * pts.size() / p.max_points]);
    pts.swap(thin);
  }
  Alignment out;
  const Eigen::Isometry3d identity = Eigen::Isometry3d::Identity();
  {
    const auto a0 = accumulate(pts, other, kFinest, identity, 0, p, false);
    if (a0.n < p.min_points) return std::nullopt;
    const double b0 = a0.residual_sum / a0.weights;
    const auto a1 = accumulate(pts, other, kFinest, identity, b0, p, false);
    out.error_before = a1.error / std::max(a1.weights, 1e-12);
  }
  Eigen::Isometry3d c = identity;
  double bias = 0;
  for (int level = kCoarsest; level >= kFinest; --level) {
    for (int it = 0; it < kIterations; ++it) {
      const auto a = accumulate(pts, other, level, c, bias, p, true);
      if (a.n < p.min_points) return std::nullopt;
      bias = a.residual_sum / a.weights;
      Eigen::Matrix<double, 6, 6> H = a.H;
      H.diagonal() *= 1.0 + 1e-3;  // Levenberg damping
      const Eigen::Matrix<double, 6, 1> d = H.ldlt().solve(-a.g);
      if (!d.allFinite()) return std::nullopt;
      Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
      const double angle = d.tail<3>().norm();
      if (angle > 0)
        step.linear() = Eigen::AngleAxisd(angle, d.tail<3>() / angle).toRotationMatrix();
      step.translation() = d.head<3>();
      c = step * c;
      if (d.head<3>().norm() < 1e-4 && angle < 1e-5) break;
    }
  }
  const auto af = accumulate(pts, other, kFinest, c, bias, p, false);
  out.points = af.n;
  out.error_after = af.error / std::max(af.weights, 1e-12);
  out.correction = c;
  const double rot_deg = Eigen::AngleAxisd(c.linear()).angle() * 180 / M_PI;
  const double shift = c.translation().norm();
  const double gain = shift > p.small_translation ? p.large_gain : p.min_gain;
  if (af.n < p.min_points || shift > p.max_translation || rot_deg > p.max_rotation_deg ||
      !(out.error_after < (1 - gain) * out.error_before))
    return std::nullopt;
  return out;
}

}  // namespace cleanmap::vision
