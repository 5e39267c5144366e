// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/vision/rectify.h"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <utility>

#include "cleanmap/core/error.h"

namespace cleanmap::vision {

Eigen::Vector2d distortNormalised(const Lens& lens, const Eigen::Vector2d& xy) {
  const auto& k = lens.k;
  const double x = xy.x(), y = xy.y(), r2 = x * x + y * y;
  if (lens.model == LensModel::kKannalaBrandt) {
    const double r = std::sqrt(r2);
    if (r < 1e-12) return xy;
    const double th = std::atan(r), t2 = th * th;
    const double thd = th * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
    return xy * (thd / r);
  }
  // OpenCV's model: k1 k2 p1 p2 k3 k4 k5 k6.
  const double radial =
      (1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]))) / (1 + r2 * (k[5] + r2 * (k[6] + r2 * k[7])));
  return {x * radial + 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x),
          y * radial + k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y};
}

namespace {
// Output pixel (u, v) of focal scale s: ray ((u - cx) / (s fx), (v - cy) / (s fy)), through the
// lens, to the distorted image's pixel.
Eigen::Vector2d sourcePixel(const Eigen::Matrix3d& K, const Lens& lens, double s, double u,
                            double v) {
  const Eigen::Vector2d xy((u - K(0, 2)) / (s * K(0, 0)), (v - K(1, 2)) / (s * K(1, 1)));
  const Eigen::Vector2d d = distortNormalised(lens, xy);
  return Eigen::Vector2d(K(0, 0) * d.x() + K(0, 1) * d.y() + K(0, 2), K(1, 1) * d.y() + K(1, 2));
}
}  // namespace

Rectifier::Rectifier(const Eigen::Matrix3d& K, const Lens& lens, int width, int height,
                     const std::string& source)
    : K_(K), lens_(lens), width_(width), height_(height) {
  if (width < 2 || height < 2 || !(K(0, 0) > 0) || !(K(1, 1) > 0))
    throw Error(source, "camera intrinsics or image size not usable for undistortion");
  auto source_pixel = [&](double s, double u, double v) { return sourcePixel(K, lens, s, u, v); };
  // The image border, sampled every 8 px and at the corners; a scale is valid if every sample
  // lands inside the distorted image. The smallest valid scale keeps the widest view.
  auto valid = [&](double s) {
    auto inside = [&](double u, double v) {
      const Eigen::Vector2d p = source_pixel(s, u, v);
      return p.allFinite() && p.x() >= 0 && p.y() >= 0 && p.x() <= width - 1 && p.y() <= height - 1;
    };
    // A polynomial lens folds beyond its field of view (the distorted radius falls again): along
    // the ray to each corner, the distorted distance from the principal point must keep growing.
    const Eigen::Vector2d c(K(0, 2), K(1, 2));
    for (const auto& [cu, cv] :
         {std::pair{0.0, 0.0}, std::pair{width - 1.0, 0.0}, std::pair{0.0, height - 1.0},
          std::pair{width - 1.0, height - 1.0}}) {
      double last = 0;
      for (int i = 1; i <= 64; ++i) {
        const double f = i / 64.0;
        const double d =
            (source_pixel(s, c.x() + f * (cu - c.x()), c.y() + f * (cv - c.y())) - c).norm();
        if (!(d > last)) return false;
        last = d;
      }
    }
    for (int u = 0; u < width; u += 8)
      if (!inside(u, 0) || !inside(u, height - 1)) return false;
    for (int v = 0; v < height; v += 8)
      if (!inside(0, v) || !inside(width - 1, v)) return false;
    return inside(width - 1, 0) && inside(width - 1, height - 1) && inside(0, height - 1);
  };
  double lo = 0.25, hi = 4.0;
  if (!valid(hi))
    throw Error(source, "the camera's lens distortion folds the image: it cannot be undistorted");
  if (valid(lo)) hi = lo;
  for (int it = 0; it < 40 && hi - lo > 1e-6; ++it) {
    const double mid = 0.5 * (lo + hi);
    (valid(mid) ? hi : lo) = mid;
  }
  scale_ = hi;
  K_new_ = K;
  K_new_(0, 0) *= hi;
  K_new_(0, 1) *= hi;
  K_new_(1, 1) *= hi;
}

cv::Mat Rectifier::apply(const cv::Mat& distorted) const {
  if (distorted.cols != width_ || distorted.rows != height_)
    throw Error("Rectifier", "image size differs from the camera's");
  std::call_once(maps_once_, [&] {
    cv::Mat mx(height_, width_, CV_32FC1), my(height_, width_, CV_32FC1);
    for (int v = 0; v < height_; ++v)
      for (int u = 0; u < width_; ++u) {
        const Eigen::Vector2d p = sourcePixel(K_, lens_, scale_, u, v);
        mx.at<float>(v, u) = static_cast<float>(p.x());
        my.at<float>(v, u) = static_cast<float>(p.y());
      }
    cv::convertMaps(mx, my, map1_, map2_, CV_16SC2);
  });
  cv::Mat out;
  cv::remap(distorted, out, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace cleanmap::vision
