// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.1: Generalized ICP (Segal, Haehnel, Thrun, RSS 2009) of a source cloud to a VoxelMap.
// Cost: sum_i rho(d_i^T (C_t + R C_s R^T)^-1 d_i), d_i = t_i - T s_i (eq. (2) of the paper), solved
// by Gauss-Newton with a Geman-McClure weight on |d_i|, the pose updated on the left,
// T <- [exp(w) | v] T.
#pragma once
#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "cleanmap/registration/cov_cloud.h"
#include "cleanmap/registration/voxel_map.h"

namespace cleanmap::reg {

struct GicpParams {
  double max_correspondence = 1.0;  ///< m; farther pairs are not correspondences (<= map voxel)
  double kernel = 0.3;              ///< m; Geman-McClure scale: weight (k^2 / (k^2 + |d|^2))^2
  int max_iterations = 30;
  double translation_eps = 1e-4;  ///< m; converged when an update moves less ...
  double rotation_eps = 1e-5;     ///< rad; ... and turns less
  /// Correspondences are searched again only once the pose moved this far since the last search
  /// (m, or rad times 10 m): the last iterations reuse them.
  double research = 0.01;
  int min_correspondences = 50;
  /// A direction is degenerate when its information per inlier is below this (in-plane points
  /// give about 0.5: a scene of one plane or one corridor stays below).
  double min_information = 1.0;
};

struct GicpResult {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  int iterations = 0;
  std::size_t correspondences = 0;  ///< pairs within max_correspondence at the end
  double fitness = 0;               ///< correspondences / source points
  double rmse = 0;                  ///< m; of the correspondences at the end
  bool converged = false;
  bool degenerate = false;  ///< some translation is barely constrained (a plane, a corridor)
  /// Failed because the scan and the map barely overlap (too few correspondences, or a map of
  /// too few points): the map is elsewhere, not just the guess a little off.
  bool no_overlap = false;
  std::string failure;  ///< empty when the alignment is usable
  std::string reason;   ///< the failure without its figures (reports count refusals by it)
};

/// Aligns `source` (sensor frame, with covariances) to `target` from `guess` (sensor to world),
/// matching only the target's entries of scans up to `newest_scan`.
GicpResult alignGicp(const CovCloud& source, const VoxelMap& target, const Eigen::Isometry3d& guess,
                     const GicpParams& p, int threads, int64_t newest_scan = INT64_MAX);

/// DESIGN §2.1 "Starting at speed": how well `src` at `T` fits `target` where it says where the
/// sensor is along `axis` (a unit vector in the source's frame): over the source points whose
/// surface faces that axis (normal within 45 degrees of it), the mean of e / (e + 1) with e the
/// squared distance along the target's normal over (5 cm)^2, 1 for a point without a match
/// within max_correspondence; 1 minus that. Surfaces along the axis (a street's facades and road,
/// sampled alike by the same beams at every step) leave it unchanged. nullopt with fewer than
/// `min_points` such points.
std::optional<double> facingScore(const CovCloud& src, const VoxelMap& target,
                                  const Eigen::Isometry3d& T, const Eigen::Vector3d& axis,
                                  const GicpParams& p, int threads, std::size_t min_points,
                                  int64_t newest_scan = INT64_MAX);

}  // namespace cleanmap::reg
