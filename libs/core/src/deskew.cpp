// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/deskew.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "cleanmap/core/fast_math.h"

namespace cleanmap {

SweepMotion SweepMotion::between(const Eigen::Isometry3d& a, double ta, const Eigen::Isometry3d& b,
                                 double tb) {
  SweepMotion m;
  const double dt = tb - ta;
  if (!(dt > 0) || !std::isfinite(dt)) return m;
  const Eigen::Isometry3d delta = a.inverse() * b;  // in a's frame: constant body velocity
  const Eigen::AngleAxisd aa(delta.linear());
  m.omega = aa.axis() * (aa.angle() / dt);
  m.v = delta.translation() / dt;
  return m;
}

std::vector<float> azimuthTimes(const std::vector<PointXYZI>& points, double sweep_s) {
  std::vector<float> t(points.size());
  const float k = static_cast<float>(-sweep_s / (2.0 * M_PI));
  for (std::size_t i = 0; i < points.size(); ++i) t[i] = k * fast::atan2(points[i].y, points[i].x);
  return t;
}

double deskewPoints(std::vector<PointXYZI>& points, const std::vector<float>& times,
                    const SweepMotion& motion) {
  if (times.size() != points.size())
    throw std::invalid_argument("deskewPoints: " + std::to_string(times.size()) + " times for " +
                                std::to_string(points.size()) + " points");
  const double w = motion.omega.norm();
  if (w == 0 && motion.v.isZero()) return 0.0;
  const Eigen::Vector3d axis = w > 0 ? Eigen::Vector3d(motion.omega / w) : Eigen::Vector3d::UnitZ();
  Eigen::Matrix3d K;  // the axis' cross-product matrix
  K << 0, -axis.z(), axis.y(), axis.z(), 0, -axis.x(), -axis.y(), axis.x(), 0;
  const Eigen::Matrix3d K2 = K * K;
  double max_shift2 = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double t = times[i];
    const double th = w * t;
    // Rodrigues: R = I + sin(th) K + (1 - cos(th)) K^2. A sweep turns a few degrees at most, where
    // the series to th^4 is within 1e-7 (|th| < 0.1); std::sin / cos beyond.
    double s, c1;
    if (std::abs(th) < 0.1) {
      const double th2 = th * th;
      s = th * (1.0 - th2 * (1.0 / 6.0));
      c1 = th2 * (0.5 - th2 * (1.0 / 24.0));
    } else {
      s = std::sin(th);
      c1 = 1.0 - std::cos(th);
    }
    const Eigen::Vector3d p = points[i].xyz().cast<double>();
    const Eigen::Vector3d q = p + s * (K * p) + c1 * (K2 * p) + t * motion.v;
    max_shift2 = std::max(max_shift2, (q - p).squaredNorm());
    points[i].x = static_cast<float>(q.x());
    points[i].y = static_cast<float>(q.y());
    points[i].z = static_cast<float>(q.z());
  }
  return std::sqrt(max_shift2);
}

}  // namespace cleanmap
