// SPDX-License-Identifier: BSD-3-Clause
// vision::Rectifier (DESIGN §3, "Lens distortion"): a distorted camera's image resampled to a
// pinhole camera puts each ray where the pinhole model projects it.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "cleanmap/core/error.h"
#include "cleanmap/vision/rectify.h"
#include "test_data.h"

using namespace cleanmap;
using vision::Lens;
using vision::LensModel;
using vision::Rectifier;

namespace {

Eigen::Matrix3d intrinsics() {
  Eigen::Matrix3d K;
  K << 500, 0, 330, 0, 480, 235, 0, 0, 1;
  return K;
}

// Bright dots where a grid of rays lands through the lens, on black; after rectification each dot
// must lie where the rectified pinhole camera projects its ray (within half a pixel).
void expectRaysWherePinholeProjects(const Lens& lens) {
  const int w = 640, h = 480;
  const Eigen::Matrix3d K = intrinsics();
  const Rectifier rect(K, lens, w, h, "test camera");
  cv::Mat distorted(h, w, CV_8UC3, cv::Scalar::all(0));
  std::vector<Eigen::Vector2d> rays;
  for (double x = -0.6; x <= 0.61; x += 0.15)
    for (double y = -0.45; y <= 0.46; y += 0.15) {
      const Eigen::Vector2d d = vision::distortNormalised(lens, {x, y});
      const cv::Point2d p(K(0, 0) * d.x() + K(0, 2), K(1, 1) * d.y() + K(1, 2));
      if (p.x < 4 || p.y < 4 || p.x > w - 5 || p.y > h - 5) continue;
      cv::circle(distorted, cv::Point(int(std::lround(p.x * 16)), int(std::lround(p.y * 16))), 40,
                 cv::Scalar::all(255), cv::FILLED, cv::LINE_AA, 4);  // radius 2.5 px, subpixel
      rays.emplace_back(x, y);
    }
  ASSERT_GT(rays.size(), 30u);
  const cv::Mat out = rect.apply(distorted);
  ASSERT_EQ(out.size(), distorted.size());
  cv::Mat grey;
  cv::cvtColor(out, grey, cv::COLOR_BGR2GRAY);
  const Eigen::Matrix3d& Kn = rect.K();
  std::size_t checked = 0;
  for (const auto& r : rays) {
    const double u = Kn(0, 0) * r.x() + Kn(0, 2), v = Kn(1, 1) * r.y() + Kn(1, 2);
    if (u < 8 || v < 8 || u > w - 9 || v > h - 9) continue;  // zoomed out of view
    double sum = 0, su = 0, sv = 0;  // the dot's centroid in a 13 x 13 window
    for (int dv = -6; dv <= 6; ++dv)
      for (int du = -6; du <= 6; ++du) {
        const int x = int(std::lround(u)) + du, y = int(std::lround(v)) + dv;
        const double g = grey.at<uint8_t>(y, x);
        sum += g;
        su += g * x;
        sv += g * y;
      }
    ASSERT_GT(sum, 1000) << "no dot near " << u << ", " << v;
    EXPECT_NEAR(su / sum, u, 0.5) << "ray " << r.transpose();
    EXPECT_NEAR(sv / sum, v, 0.5) << "ray " << r.transpose();
    ++checked;
  }
  EXPECT_GT(checked, 20u);
}

}  // namespace

TEST(Rectify, NoDistortionIsTheIdentity) {
  const Lens none;
  EXPECT_EQ(vision::distortNormalised(none, {0.3, -0.2}), Eigen::Vector2d(0.3, -0.2));
  const Rectifier rect(intrinsics(), none, 640, 480, "test camera");
  EXPECT_NEAR((rect.K() - intrinsics()).cwiseAbs().maxCoeff(), 0.0, 1e-3);
  cv::Mat img(480, 640, CV_8UC3);
  cv::randu(img, cv::Scalar::all(0), cv::Scalar::all(255));
  EXPECT_LE(cv::norm(rect.apply(img), img, cv::NORM_INF), 1.0);
}

TEST(Rectify, BarrelLensRaysLandWherePinholeProjects) {
  Lens lens;  // a wide lens: barrel with some tangential decentring
  lens.k = {-0.28, 0.09, 0.001, -0.0005, -0.01, 0, 0, 0};
  expectRaysWherePinholeProjects(lens);
  // A barrel lens sees wider than its pinhole core: the rectified view keeps more of it (a
  // shorter focal length) up to where the edges' midpoints reach the image's.
  EXPECT_LT(Rectifier(intrinsics(), lens, 640, 480, "c").K()(0, 0), intrinsics()(0, 0));
}

TEST(Rectify, PincushionLensRaysLandWherePinholeProjects) {
  Lens lens;
  lens.k = {0.2, 0.05, 0, 0, 0, 0, 0, 0};
  expectRaysWherePinholeProjects(lens);
  // Its corners reach beyond the image: the rectified view is zoomed in (no empty pixels).
  EXPECT_GT(Rectifier(intrinsics(), lens, 640, 480, "c").K()(0, 0), intrinsics()(0, 0));
}

TEST(Rectify, FisheyeRaysLandWherePinholeProjects) {
  Lens lens;
  lens.model = LensModel::kKannalaBrandt;
  lens.k = {-0.05, 0.01, -0.002, 0.0005, 0, 0, 0, 0};
  expectRaysWherePinholeProjects(lens);
}

TEST(Rectify, ALensThatFoldsTheImageIsAClearError) {
  Lens lens;
  lens.k = {-40, 0, 0, 0, 0, 0, 0, 0};  // the radius turns back within 0.16 of the axis
  test::expectError([&] { Rectifier(intrinsics(), lens, 640, 480, "run.rawlog camera 'CAM'"); },
                    "run.rawlog camera 'CAM'", "lens distortion folds the image");
  const Rectifier ok(intrinsics(), Lens{}, 640, 480, "c");
  test::expectError([&] { ok.apply(cv::Mat(10, 10, CV_8UC3)); }, "Rectifier", "image size differs");
}
