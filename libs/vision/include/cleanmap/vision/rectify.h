// SPDX-License-Identifier: BSD-3-Clause
// Images of a camera with lens distortion made pinhole (DESIGN §3, "Lens distortion"): the image
// validation projects lidar points with a pinhole model, so a distorted image is resampled once
// per frame to a pinhole camera whose every pixel sees the scene.
#pragma once
#include <Eigen/Core>
#include <array>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>

namespace cleanmap::vision {

enum class LensModel {
  kPlumbBob,       ///< radial and tangential (OpenCV's): k1 k2 p1 p2 k3 k4 k5 k6
  kKannalaBrandt,  ///< equidistant fisheye: theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8)
};

struct Lens {
  LensModel model = LensModel::kPlumbBob;
  /// kPlumbBob: k1 k2 p1 p2 k3 k4 k5 k6 (rational model when k4-k6 are set); kKannalaBrandt: k1 k2
  /// k3 k4 in the first four.
  std::array<double, 8> k{};
};

/// Where a ray (x, y, 1) in the camera's frame lands in normalised image coordinates through the
/// lens (before the intrinsics).
Eigen::Vector2d distortNormalised(const Lens& lens, const Eigen::Vector2d& xy);

/// Resamples a distorted camera's images (intrinsics K, size width x height) to a pinhole camera
/// of the same size and principal point whose focal length is scaled so that every one of its
/// pixels maps inside the distorted image (no black borders: barrel lenses are zoomed in). The
/// mapping is computed once, by the first image applied: the size a calibration claims costs
/// nothing until an image of that size comes (a rawlog's camera of 8200 x 16384 pixels took 7 s
/// and 1.9 GB before its 8 x 4 image was refused). Throws cleanmap::Error (naming `source`) if the
/// lens folds the image (no scale keeps the border inside).
class Rectifier {
 public:
  Rectifier(const Eigen::Matrix3d& K, const Lens& lens, int width, int height,
            const std::string& source);
  /// The pinhole intrinsics of the rectified images.
  const Eigen::Matrix3d& K() const { return K_new_; }
  /// The rectified image (bilinear).
  cv::Mat apply(const cv::Mat& distorted) const;

 private:
  Eigen::Matrix3d K_, K_new_;
  Lens lens_;
  double scale_ = 1;  // K_new_'s focal lengths over K_'s
  int width_, height_;
  mutable std::once_flag maps_once_;
  mutable cv::Mat map1_, map2_;
};

}  // namespace cleanmap::vision
