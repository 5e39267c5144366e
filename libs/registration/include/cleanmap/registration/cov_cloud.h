// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.1: points with the covariance of their local surface, the input of GICP (Segal et al.
// 2009, §III-B): each covariance comes from the k nearest neighbours and is regularised to a plane.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace cleanmap::reg {

/// Points and, per point, a plane-regularised covariance (same frame). `source[i]` is the index of
/// the input point each one stands for (downsampling keeps the first point of each voxel).
struct CovCloud {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Matrix3d> covs;
  std::vector<uint32_t> source;
  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
};

/// Indices of the first input point of each voxel of side `voxel`, in input order (deterministic).
std::vector<uint32_t> voxelDownsample(const std::vector<Eigen::Vector3d>& points, double voxel);

/// The GICP covariance of each point of `points` from its `knn` nearest neighbours within `radius`
/// in the same cloud: C = V diag(eps, 1, 1) V^T, V the eigenvectors of the neighbours' sample
/// covariance sorted by increasing eigenvalue (the plane model of Segal et al., eq. (2)). A point
/// with fewer than 5 neighbours gets an isotropic covariance (it constrains no plane).
std::vector<Eigen::Matrix3d> planeCovariances(const std::vector<Eigen::Vector3d>& points, int knn,
                                              double radius, double eps, int threads);

}  // namespace cleanmap::reg
