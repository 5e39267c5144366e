// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/registration/gicp.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "cleanmap/core/parallel.h"

namespace cleanmap::reg {
namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// The normal equations of one linearisation. Summed per fixed block of points, then over the
// blocks in order: the same floating-point sums whatever the thread count (reproducible runs).
struct Normal {
  Mat6 H = Mat6::Zero();
  Vec6 g = Vec6::Zero();
  Eigen::Matrix3d Htt = Eigen::Matrix3d::Zero();  // unweighted translation information
  double sq = 0;
  std::size_t n = 0;
  void add(const Normal& o) {
    H += o.H;
    g += o.g;
    Htt += o.Htt;
    sq += o.sq;
    n += o.n;
  }
};

}  // namespace

GicpResult alignGicp(const CovCloud& src, const VoxelMap& target, const Eigen::Isometry3d& guess,
                     const GicpParams& p, int threads, int64_t newest_scan) {
  GicpResult r;
  r.T = guess;
  if (src.size() < static_cast<std::size_t>(p.min_correspondences)) {
    r.failure = "too few points (" + std::to_string(src.size()) + ")";
    r.reason = "too few points";
    return r;
  }
  if (target.size() < static_cast<std::size_t>(p.min_correspondences)) {
    r.failure = "the map holds too few points (" + std::to_string(target.size()) + ")";
    r.reason = "the map holds too few points";
    r.no_overlap = true;
    return r;
  }
  constexpr std::size_t kBlock = 256;
  const std::size_t blocks = (src.size() + kBlock - 1) / kBlock;
  std::vector<VoxelMap::Match> match(src.size());
  Eigen::Isometry3d searched_at = r.T;
  bool search = true;
  const double k2 = p.kernel * p.kernel;
  Normal total;
  for (int it = 0; it < p.max_iterations; ++it) {
    const Eigen::Matrix3d R = r.T.linear();
    if (search) {
      parallelFor(src.size(), threads, [&](std::size_t i) {
        match[i] = target.nearest(r.T * src.points[i], p.max_correspondence, newest_scan);
      });
      searched_at = r.T;
      search = false;
    }
    std::vector<Normal> acc(blocks);
    parallelFor(
        blocks, threads,
        [&](std::size_t b) {
          Normal& a = acc[b];
          for (std::size_t i = b * kBlock; i < std::min(src.size(), (b + 1) * kBlock); ++i) {
            const VoxelMap::Match& m = match[i];
            if (!m) continue;
            const Eigen::Vector3d q = r.T * src.points[i];
            const Eigen::Vector3d d = *m.p - q;  // residual t - T s
            const double d2 = d.squaredNorm();
            const Eigen::Matrix3d M = (*m.cov + R * src.covs[i] * R.transpose()).inverse();
            const double wk = k2 / (k2 + d2);
            const double weight = wk * wk;  // Geman-McClure
            Eigen::Matrix<double, 3, 6> J;  // d(residual) / d(w, v) for T <- [exp(w) | v] T
            J.leftCols<3>() = skew(q);
            J.rightCols<3>() = -Eigen::Matrix3d::Identity();
            const Eigen::Matrix<double, 6, 3> JtM = J.transpose() * M;
            a.H.noalias() += weight * JtM * J;
            a.g.noalias() += weight * JtM * d;
            a.Htt += M;
            a.sq += d2;
            ++a.n;
          }
        },
        1);
    total = Normal{};
    for (const auto& a : acc) total.add(a);
    r.iterations = it + 1;
    if (total.n < static_cast<std::size_t>(p.min_correspondences)) {
      r.failure = "too few correspondences (" + std::to_string(total.n) + ")";
      r.reason = "too few correspondences";
      r.no_overlap = true;
      return r;
    }
    const Vec6 delta = total.H.ldlt().solve(-total.g);
    if (!delta.allFinite()) {
      r.failure = r.reason = "the normal equations are singular";
      return r;
    }
    const Eigen::Vector3d w = delta.head<3>(), v = delta.tail<3>();
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    if (w.norm() > 0)
      step.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    step.translation() = v;
    r.T = step * r.T;
    const Eigen::Isometry3d moved = searched_at.inverse() * r.T;
    search =
        moved.translation().norm() + 10.0 * Eigen::AngleAxisd(moved.linear()).angle() > p.research;
    if (v.norm() < p.translation_eps && w.norm() < p.rotation_eps) {
      r.converged = true;
      break;
    }
  }
  r.correspondences = total.n;
  r.fitness = static_cast<double>(total.n) / static_cast<double>(src.size());
  r.rmse = std::sqrt(total.sq / static_cast<double>(std::max<std::size_t>(total.n, 1)));
  // Degeneracy: the least-constrained translation direction, per correspondence.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(total.Htt);
  if (es.eigenvalues()(0) / static_cast<double>(total.n) < p.min_information) {
    r.degenerate = true;
    r.failure = "degenerate scene (a translation is unconstrained: one plane or one corridor)";
    r.reason = "degenerate scene";
  }
  return r;
}

std::optional<double> facingScore(const CovCloud& src, const VoxelMap& target,
                                  const Eigen::Isometry3d& T, const Eigen::Vector3d& axis,
                                  const GicpParams& p, int threads, std::size_t min_points,
                                  int64_t newest_scan) {
  // A plane covariance is I - (1 - eps) n n^T: (n . a)^2 = a^T (I - C) a / (1 - eps), and the
  // squared distance along the target's n is d^T (I - C_t) d / (1 - eps); 3 - trace = 1 - eps.
  std::vector<uint32_t> facing;
  for (uint32_t i = 0; i < src.size(); ++i) {
    const Eigen::Matrix3d& C = src.covs[i];
    const double flat = 3.0 - C.trace();
    if (flat < 0.5) continue;  // no plane (identity: too few neighbours)
    if (axis.dot((Eigen::Matrix3d::Identity() - C) * axis) / flat > 0.5) facing.push_back(i);
  }
  if (facing.size() < min_points) return std::nullopt;
  std::vector<double> loss(facing.size(), 1.0);
  parallelFor(facing.size(), threads, [&](std::size_t k) {
    const uint32_t i = facing[k];
    const Eigen::Vector3d q = T * src.points[i];
    const VoxelMap::Match m = target.nearest(q, p.max_correspondence, newest_scan);
    if (!m) return;
    const Eigen::Matrix3d& Ct = *m.cov;
    const double flat = 3.0 - Ct.trace();
    const Eigen::Vector3d d = *m.p - q;
    const double e =
        (flat < 0.5 ? d.squaredNorm() : d.dot((Eigen::Matrix3d::Identity() - Ct) * d) / flat) /
        (0.05 * 0.05);
    loss[k] = e / (e + 1.0);
  });
  double sum = 0;
  for (const double l : loss) sum += l;
  return 1.0 - sum / static_cast<double>(facing.size());
}

}  // namespace cleanmap::reg
