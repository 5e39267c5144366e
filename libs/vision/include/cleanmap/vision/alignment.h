// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §3 "Camera poses": a camera's pose relative to another's, corrected by direct photometric
// alignment of its image on the other scan's lidar returns (the pipeline: each scan on the one
// before, on its ground returns).
#pragma once
#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "cleanmap/vision/image_validation.h"

namespace cleanmap::vision {

struct AlignParams {
  int max_points = 1000;         ///< reference points used (the textured ones, evenly thinned)
  int min_points = 100;          ///< fewer textured points in both images: no correction
  double min_gradient = 0.02;    ///< intensity step per pixel (half resolution) to be textured
  double huber = 0.05;           ///< intensity residual beyond which a point's weight falls
  double occlusion = 0.5;        ///< m; a point behind other's own nearer return is not compared
  double max_translation = 0.5;  ///< m; a larger correction is rejected (beyond any drift)
  double max_rotation_deg = 1.0;
  /// The robust error must fall by this fraction: real images' noise (exposure, blur) leaves
  /// a few tens of percent that a wrong pose can explain too (kitti_highway: 10-28 %).
  double min_gain = 0.3;
  /// m; a larger correction must lower the error by `large_gain`: a true misalignment that
  /// large leaves most of the error (the simulated drift's: 83-93 %), a wrong minimum (aliasing,
  /// a mover's pull) explains only the noise (58 % at most measured; DESIGN §3 "Camera poses").
  double small_translation = 0.15;
  double large_gain = 0.7;
};

struct Alignment {
  /// Applied to `other`: its corrected optical_from_world is correction * optical_from_world.
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
  int points = 0;                            ///< reference points compared at the finest level
  double error_before = 0, error_after = 0;  ///< robust mean squared residual, half resolution
};

/// Aligns `other` on `ref`: the pose of other's camera that makes its image agree, at the
/// projections of `static_world` (world frame; returns of ref's scan that do not move), with ref's
/// image. Gauss-Newton on the intensity residuals (Huber weights, a common brightness offset),
/// 6 degrees of freedom, over levels 3, 2, 1 of the image pyramids (CameraView::grey). Nullopt
/// when too few textured points are seen by both, or the result is rejected (too large, or the
/// error did not fall by min_gain, or by large_gain beyond small_translation).
std::optional<Alignment> alignView(const CameraView& ref, const CameraView& other,
                                   const std::vector<Eigen::Vector3d>& static_world,
                                   const AlignParams& p);

/// `v` with its optical_from_world and centre corrected by `correction` (images shared).
CameraView corrected(const CameraView& v, const Eigen::Isometry3d& correction);

}  // namespace cleanmap::vision
