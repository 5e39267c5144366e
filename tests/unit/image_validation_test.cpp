// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §3 on synthetic images with known answers: a textured wall 10 m ahead of a camera that
// moves 0.5 m sideways, rendered exactly, with and without a box in front of it that is there
// only in the first view (a mover that left).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "cleanmap/core/error.h"
#include "cleanmap/vision/image_validation.h"
#include "test_data.h"

using namespace cleanmap;

namespace {

constexpr int kW = 320, kH = 240;
constexpr double kF = 600, kWall = 10.0;

// Lidar frame = camera optical frame (x right, y down, z forward).
PinholeCamera camera() {
  PinholeCamera c;
  c.width = kW;
  c.height = kH;
  c.P << kF, 0, kW / 2.0, 0, 0, kF, kH / 2.0, 0, 0, 0, 1, 0;
  c.name = "test";
  return c;
}

// A random blocky texture (10 cm cells: 6 px at 10 m) of a plane, seeded.
cv::Vec3b texel(double x, double y, uint32_t seed, bool flat) {
  if (flat) return {90, 120, 150};
  const auto ix = static_cast<uint32_t>(std::floor(x / 0.1) + 100000),
             iy = static_cast<uint32_t>(std::floor(y / 0.1) + 100000);
  uint32_t h = ix * 73856093u ^ iy * 19349663u ^ seed * 83492791u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return {uchar(40 + h % 180), uchar(40 + (h >> 8) % 180), uchar(40 + (h >> 16) % 180)};
}

// The scene: the wall at z = 10 (texture seed 1), optionally a box face at z = 8 for
// |x - 0.1| < 0.5, |y| < 0.5 (seed 2), seen from a camera at (cx, 0, 0).
struct Scene {
  bool box = false, flat = false;
};

cv::Mat render(const Scene& sc, double cx) {
  cv::Mat img(kH, kW, CV_8UC3);
  for (int v = 0; v < kH; ++v)
    for (int u = 0; u < kW; ++u) {
      const double dx = (u + 0.5 - kW / 2.0) / kF, dy = (v + 0.5 - kH / 2.0) / kF;
      const double bx = cx + dx * 8, by = dy * 8;
      if (sc.box && std::abs(bx - 0.1) < 0.5 && std::abs(by) < 0.5)
        img.at<cv::Vec3b>(v, u) = texel(bx, by, 2, sc.flat);
      else
        img.at<cv::Vec3b>(v, u) = texel(cx + dx * kWall, dy * kWall, 1, sc.flat);
    }
  return img;
}

// Lidar points (in the sensor frame of a sensor at (cx, 0, 0)): a 2 cm grid on the wall and the
// box, each only where visible.
std::vector<PointXYZI> points(const Scene& sc, double cx) {
  std::vector<PointXYZI> pts;
  for (double x = -3; x <= 3; x += 0.02)
    for (double y = -2; y <= 2; y += 0.02) {
      const double bx = x * 8 / kWall, by = y * 8 / kWall;  // where the ray to (x, y, 10) is at z 8
      if (sc.box && std::abs(bx - 0.1) < 0.5 && std::abs(by) < 0.5) continue;
      pts.push_back({float(x - cx), float(y), float(kWall), 0.f});
    }
  if (sc.box)
    for (double x = -0.4; x < 0.6; x += 0.02)
      for (double y = -0.49; y < 0.5; y += 0.02) pts.push_back({float(x - cx), float(y), 8.f, 0.f});
  return pts;
}

Eigen::Isometry3d at(double cx) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(cx, 0, 0);
  return T;
}

vision::CameraView view(const Scene& sc, double cx, std::size_t index) {
  return vision::makeCameraView(render(sc, cx), points(sc, cx), at(cx), camera(), index, "test", 4);
}

cv::Mat asFloat(const cv::Mat& m) {
  cv::Mat f;
  m.convertTo(f, CV_32FC3, 1.0 / 255);
  return f;
}

}  // namespace

TEST(ImageValidation, TheSamePatchIsSimilar) {
  const cv::Mat img = asFloat(render({}, 0));
  const cv::Mat patch = img(cv::Rect(100, 100, 15, 15));
  EXPECT_TRUE(vision::isTextured(patch, 0.02));
  EXPECT_LT(vision::colourError(patch, patch), 1e-4);
}

TEST(ImageValidation, ATextureShiftedWithinTheMarginIsSimilarAndADifferentOneIsNot) {
  const cv::Mat img = asFloat(render({}, 0));
  const cv::Mat tmpl = img(cv::Rect(150, 100, 15, 15));
  // The region around a spot 6 px away, searched +-8 px: it holds the template.
  EXPECT_LT(vision::colourError(tmpl, img(cv::Rect(150 + 6 - 8, 100 - 3 - 8, 31, 31))), 1e-4);
  // A region that does not hold it (shifted by 20 px, beyond the margin) ...
  EXPECT_GT(vision::colourError(tmpl, img(cv::Rect(150 + 20 - 8, 100 - 8, 31, 31))), 0.1);
  // ... nor another texture.
  const cv::Mat other = asFloat(render({true, false}, 0));
  EXPECT_GT(vision::colourError(tmpl, other(cv::Rect(150 - 8, 100 - 8, 31, 31))), 0.1);
}

TEST(ImageValidation, AStaticTexturedWallIsSimilarFromAnotherViewpoint) {
  const auto a = view({}, 0, 0), b = view({}, 0.5, 1);
  const Eigen::Vector3d p(0.3, 0.2, kWall);  // world = frame of view a
  EXPECT_EQ(vision::compareViews(a, b, p, ImageParams{}), vision::Verdict::kSimilarColour);
  // A 10 cm pose error moves the projection 6 px: found within the default margin (0.15 m,
  // 9 px at 10 m), not without one.
  ImageParams none;
  none.search_margin = 0;
  auto b_shifted = b;
  b_shifted.optical_from_world.translation().x() += 0.1;
  EXPECT_EQ(vision::compareViews(a, b_shifted, p, none), vision::Verdict::kDifferentColour);
  EXPECT_EQ(vision::compareViews(a, b_shifted, p, ImageParams{}), vision::Verdict::kSimilarColour);
}

TEST(ImageValidation, SurfaceNormalOfAPlaneButNotOfALineOrAFewPoints) {
  // A tilted plane (normal along (0, -sin 30, cos 30)), 3 cm grid over 0.6 m.
  const Eigen::Vector3d n(0, -std::sin(M_PI / 6), std::cos(M_PI / 6));
  const Eigen::Vector3d u(1, 0, 0), v = n.cross(u);
  std::vector<Eigen::Vector3d> plane, line;
  for (double a = -0.3; a <= 0.3; a += 0.03)
    for (double b = -0.3; b <= 0.3; b += 0.03)
      plane.push_back(Eigen::Vector3d(2, 1, 10) + a * u + b * v);
  for (double a = -0.3; a <= 0.3; a += 0.03) line.push_back(Eigen::Vector3d(2, 1, 10) + a * u);
  const auto got = vision::surfaceNormal(plane);
  ASSERT_TRUE(got.has_value());
  EXPECT_NEAR(std::abs(got->dot(n)), 1.0, 1e-9);
  EXPECT_FALSE(vision::surfaceNormal(line).has_value());  // a lidar ring on its own: no plane
  EXPECT_FALSE(vision::surfaceNormal({plane.begin(), plane.begin() + 5}).has_value());
}

TEST(ImageValidation, ACameraThatSeesTheSurfaceGrazingDoesNotCompare) {
  // The incidence is the angle between the ray and the normal, whichever side the normal faces.
  const Eigen::Vector3d o = Eigen::Vector3d::Zero(), x(0, 0, 10);
  const auto tilted = [](double deg) {
    return Eigen::Vector3d(std::sin(deg * M_PI / 180), 0, -std::cos(deg * M_PI / 180));
  };
  EXPECT_FALSE(vision::grazing(o, x, tilted(55), 60));
  EXPECT_FALSE(vision::grazing(o, x, -tilted(55), 60));
  EXPECT_TRUE(vision::grazing(o, x, tilted(65), 60));
  EXPECT_FALSE(vision::grazing(o, x, tilted(89), 90));               // 90: every camera compares
  EXPECT_FALSE(vision::grazing(o, x, Eigen::Vector3d::Zero(), 60));  // no surface known
  // The textured wall from two viewpoints: compared (and similar) with its own normal or none;
  // not compared if its surface were seen edge-on, or in one camera only beyond the limit.
  const auto a = view({}, 0, 0), b = view({}, 0.5, 1);
  const Eigen::Vector3d p(0.3, 0.2, kWall);
  ImageParams ip;
  ip.max_incidence_deg = 60;  // the rule on (off by default, DESIGN §3)
  EXPECT_EQ(vision::compareViews(a, b, p, ip, Eigen::Vector3d(0, 0, -1)),
            vision::Verdict::kSimilarColour);
  EXPECT_EQ(vision::compareViews(a, b, p, ip), vision::Verdict::kSimilarColour);
  EXPECT_EQ(vision::compareViews(a, b, p, ip, Eigen::Vector3d(1, 0, 0)), vision::Verdict::kGrazing);
  // Turned toward camera a (at x 0) so that it sees the wall at 57.4 deg, camera b (x 0.5) at
  // 60.3 deg.
  const double off_b = std::atan2(0.5 - 0.3, kWall) * 180 / M_PI;  // b's ray, off the z axis
  const Eigen::Vector3d n = tilted(-(60.0 - off_b + 0.3));
  EXPECT_FALSE(vision::grazing(a.centre, p, n, 60));
  EXPECT_TRUE(vision::grazing(b.centre, p, n, 60));
  EXPECT_EQ(vision::compareViews(a, b, p, ip, n), vision::Verdict::kGrazing);
  // decide() counts it and does not let it vote: seen by no camera that compares.
  const auto d = vision::decide(a, {&b}, p, ip, n);
  EXPECT_EQ(d.grazing, 1);
  EXPECT_EQ(d.views, 0);
  EXPECT_FALSE(d.relabel_static || d.confirmed);
  ImageParams all = ip;
  all.max_incidence_deg = 90;
  EXPECT_EQ(vision::compareViews(a, b, p, all, Eigen::Vector3d(1, 0, 0)),
            vision::Verdict::kSimilarColour);
}

// Issue #16: the view keeps its returns row by row and dilates the depth map patch by patch; both
// must give exactly what the full-image maps gave (random returns, several on one pixel, patches
// on the image's borders).
TEST(ImageValidation, TheDepthMapsPatchByPatchEqualTheWholeImageMaps) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pu(-20, kW + 20), pv(-20, kH + 20), pd(2, 40);
  std::vector<PointXYZI> pts;
  for (int i = 0; i < 3000; ++i) {
    const double u = pu(rng), v = pv(rng), z = pd(rng);
    const int copies = i % 10 == 0 ? 3 : 1;  // the nearest of a pixel's returns counts
    for (int c = 0; c < copies; ++c) {
      const double zc = z + c;
      pts.push_back(
          {float((u - kW / 2.0) / kF * zc), float((v - kH / 2.0) / kF * zc), float(zc), 0.f});
    }
  }
  const cv::Mat black(kH, kW, CV_8UC3, cv::Scalar::all(0));
  auto v = vision::makeCameraView(black, pts, at(0), camera(), 0, "test", 4);
  ASSERT_FALSE(v.sparse.empty());
  const cv::Mat full = v.returns->dense(cv::Rect(0, 0, kW, kH));
  EXPECT_EQ(cv::countNonZero(full != v.sparse), 0);
  EXPECT_GT(cv::countNonZero(full < std::numeric_limits<float>::infinity()), 1500);
  cv::Mat dilated;
  cv::erode(full, dilated, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(9, 9)),
            cv::Point(-1, -1), 1, cv::BORDER_CONSTANT,
            cv::Scalar(std::numeric_limits<float>::infinity()));
  std::uniform_int_distribution<int> side(1, 60);
  for (int i = 0; i < 300; ++i) {
    const int w = side(rng), h = side(rng);
    const int x = std::uniform_int_distribution<int>(0, kW - w)(rng);
    const int y = std::uniform_int_distribution<int>(0, kH - h)(rng);
    const cv::Rect r = i % 4 == 0   ? cv::Rect(0, y, w, h)
                       : i % 4 == 1 ? cv::Rect(kW - w, kH - h, w, h)
                                    : cv::Rect(x, y, w, h);
    const cv::Mat patch = vision::depthPatch(v, r);
    ASSERT_EQ(patch.size(), r.size());
    ASSERT_EQ(cv::countNonZero(patch != dilated(r)), 0) << "patch " << r;
  }
  std::vector<Eigen::Vector2d> px;
  std::uniform_real_distribution<double> qu(-3, kW + 3), qv(-3, kH + 3);
  for (int i = 0; i < 2000; ++i) px.emplace_back(qu(rng), qv(rng));
  std::vector<float> with_image;
  for (const auto& q : px) with_image.push_back(vision::nearestReturn(v, q));
  v.sparse.release();  // what the pipeline does once the scan is aligned
  for (std::size_t i = 0; i < px.size(); ++i)
    ASSERT_EQ(vision::nearestReturn(v, px[i]), with_image[i]) << px[i].transpose();
}

TEST(ImageValidation, AMoverThatLeftLooksDifferent) {
  const auto a = view({true, false}, 0, 0), b = view({}, 0.5, 1);
  const Eigen::Vector3d p(0.1, 0.0, 8.0);  // on the box, there in view a only
  EXPECT_EQ(vision::compareViews(a, b, p, ImageParams{}), vision::Verdict::kDifferentColour);
  const auto d = vision::decide(a, {&b}, p, ImageParams{});
  EXPECT_TRUE(d.seen);
  EXPECT_FALSE(d.relabel_static);
}

TEST(ImageValidation, AFlatPatchGoesToTheDepthTest) {
  const cv::Mat flat = asFloat(render({false, true}, 0));
  EXPECT_FALSE(vision::isTextured(flat(cv::Rect(100, 100, 15, 15)), 0.02));
  // A flat static wall is similar by depth; a flat box that left differs by depth.
  const auto a = view({false, true}, 0, 0), b = view({false, true}, 0.5, 1);
  EXPECT_EQ(vision::compareViews(a, b, {0.3, 0.2, kWall}, ImageParams{}),
            vision::Verdict::kSimilarDepth);
  const auto am = view({true, true}, 0, 0);
  EXPECT_EQ(vision::compareViews(am, b, {0.1, 0.0, 8.0}, ImageParams{}),
            vision::Verdict::kDifferentDepth);
}

TEST(ImageValidation, AnOccludedPointIsSkipped) {
  // The wall point behind the box: in view b (with the box) a nearer return hides it.
  const auto a = view({}, 0, 0), b = view({true, false}, 0, 1);
  const Eigen::Vector3d hidden(0.1 * kWall / 8, 0.0, kWall);
  EXPECT_EQ(vision::compareViews(a, b, hidden, ImageParams{}), vision::Verdict::kUnseen);
  const auto d = vision::decide(a, {&b}, hidden, ImageParams{});
  EXPECT_FALSE(d.seen);
  EXPECT_FALSE(d.relabel_static);
}

TEST(ImageValidation, APointOutsideEveryImageKeepsItsLaserLabel) {
  const auto a = view({}, 0, 0), b = view({}, 0.5, 1);
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0, 0, -5), Eigen::Vector3d(50, 0, kWall)}) {
    const auto d = vision::decide(a, {&b}, p, ImageParams{});
    EXPECT_FALSE(d.seen);
    EXPECT_FALSE(d.relabel_static);
  }
}

TEST(ImageValidation, AnImageOfTheWrongSizeIsAClearError) {
  auto cam = camera();
  cam.width = 640;
  test::expectError(
      [&] { vision::makeCameraView(render({}, 0), points({}, 0), at(0), cam, 0, "img.png", 4); },
      "img.png", "calibration");
}

// The object vote (DESIGN §3), over every outcome pattern of objects of 1-10 cells: it decides
// as the majority over every compared cell would, never decides a cell after the outcome is
// settled, and compares at most max_cells cells, spread over the object.
namespace {

vision::Decision cellDecision(int kind) {  // 0 unseen, 1 similar, 2 changed
  vision::Decision d;
  d.seen = kind != 0;
  d.views = kind != 0 ? 3 : 0;
  d.confirmed = kind == 2;
  d.relabel_static = kind == 1;
  d.decisive = kind == 2   ? vision::Verdict::kDifferentColour
               : kind == 1 ? vision::Verdict::kSimilarColour
                           : vision::Verdict::kUnseen;
  return d;
}

}  // namespace

TEST(ImageValidation, TheObjectVoteDecidesAsTheWholeMajorityAndStopsOnceSettled) {
  for (const double f : {0.0, 0.5}) {
    for (int n = 1; n <= 10; ++n) {
      int patterns = 1;
      for (int i = 0; i < n; ++i) patterns *= 3;
      for (int code = 0; code < patterns; ++code) {
        std::vector<int> kind(static_cast<std::size_t>(n));
        for (int i = 0, c = code; i < n; ++i, c /= 3) kind[std::size_t(i)] = c % 3;
        int changed = 0, similar = 0;
        for (int k : kind) changed += k == 2, similar += k == 1;
        std::vector<std::size_t> asked;
        const auto v = vision::voteObject(std::size_t(n), f, 100, [&](std::size_t i) {
          asked.push_back(i);
          return cellDecision(kind[i]);
        });
        const auto want = changed > 0 && changed >= f * (changed + similar)
                              ? vision::ObjectVote::Outcome::kMoving
                          : changed + similar > 0 ? vision::ObjectVote::Outcome::kStatic
                                                  : vision::ObjectVote::Outcome::kUnseen;
        if (v.outcome != want) {
          ADD_FAILURE() << "f " << f << ", " << n << " cells, pattern " << code;
          return;
        }
        // In order, and no cell after the outcome was settled: the cells not asked could not
        // have changed it, and without the last one asked it was still open.
        for (std::size_t j = 0; j < asked.size(); ++j) ASSERT_EQ(asked[j], j);
        EXPECT_EQ(v.compared, asked.size());
        if (asked.size() < std::size_t(n)) {
          int c = 0, s = 0;
          for (std::size_t j = 0; j < asked.size(); ++j) c += kind[j] == 2, s += kind[j] == 1;
          const int left = n - int(asked.size());
          const bool settled_moving = c > 0 && c >= f * (c + s + left);
          const bool settled_static = c + left < f * (c + s + left);
          ASSERT_TRUE(settled_moving || settled_static) << "stopped early, pattern " << code;
        }
      }
    }
  }
  // f = 0: the first changed cell settles it (the rule of one).
  const auto v =
      vision::voteObject(5, 0.0, 100, [&](std::size_t i) { return cellDecision(i == 0 ? 1 : 2); });
  EXPECT_EQ(v.outcome, vision::ObjectVote::Outcome::kMoving);
  EXPECT_EQ(v.compared, 2u);
}

TEST(ImageValidation, TheObjectVoteComparesAtMostMaxCellsSpreadOverTheObject) {
  // A 100-cell object whose first 20 cells (its extremes) look changed and the rest similar:
  // 15 cells spread over it (every sixth or seventh) see mostly similar cells, so it is static.
  std::vector<std::size_t> asked;
  auto v = vision::voteObject(100, 0.5, 15, [&](std::size_t i) {
    asked.push_back(i);
    return cellDecision(i < 20 ? 2 : 1);
  });
  EXPECT_EQ(v.outcome, vision::ObjectVote::Outcome::kStatic);
  ASSERT_LE(asked.size(), 15u);
  EXPECT_EQ(asked.front(), 0u);
  for (std::size_t j = 1; j < asked.size(); ++j) EXPECT_GE(asked[j] - asked[j - 1], 6u);
  v = vision::voteObject(100, 0.5, 15, [](std::size_t) { return cellDecision(2); });
  EXPECT_EQ(v.outcome, vision::ObjectVote::Outcome::kMoving);
  EXPECT_EQ(v.compared, 8u);  // 8 of 15 changed: a majority whatever the other 7 say
  EXPECT_EQ(v.changed_by, vision::Verdict::kDifferentColour);
  v = vision::voteObject(100, 0.5, 15, [](std::size_t) { return cellDecision(0); });
  EXPECT_EQ(v.outcome, vision::ObjectVote::Outcome::kUnseen);
  EXPECT_EQ(v.compared, 15u);
}

// The depth test's error against the formula written out (SPEC §3, DESIGN §3): random depth
// patches with gaps, the smallest error over the shifts exactly; with stop_below, the same verdict.
TEST(ImageValidation, DepthErrorIsTheSmallestShiftErrorAndStopsBelowAThreshold) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> depth(9.f, 11.f), u(0.f, 1.f);
  const float inf = std::numeric_limits<float>::infinity();
  int below = 0, above = 0, none = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const int side = 3 + trial % 6, margin = trial % 4;
    const float gaps = 0.6f * u(rng);
    cv::Mat t(side, side, CV_32F), r(side + 2 * margin, side + 2 * margin, CV_32F);
    const bool flat = trial % 3 == 0;  // a plane: some shift is well below the threshold
    for (int y = 0; y < t.rows; ++y)
      for (int x = 0; x < t.cols; ++x)
        t.at<float>(y, x) = u(rng) < gaps ? inf : flat ? 10.f : depth(rng);
    for (int y = 0; y < r.rows; ++y)
      for (int x = 0; x < r.cols; ++x)
        r.at<float>(y, x) = u(rng) < gaps ? inf : flat ? 10.2f : depth(rng);
    const double d_t = 10.0, d_r = 10.1;
    std::optional<double> want;
    for (int sy = 0; sy + side <= r.rows; ++sy)
      for (int sx = 0; sx + side <= r.cols; ++sx) {
        double sum = 0;
        int used = 0;
        for (int y = 0; y < side; ++y)
          for (int x = 0; x < side; ++x) {
            const float a = t.at<float>(y, x), b = r.at<float>(sy + y, sx + x);
            if (!std::isfinite(a) || !std::isfinite(b)) continue;
            const double ea = std::clamp((a - d_t) / d_t, -1.0, 1.0);
            const double eb = std::clamp((b - d_r) / d_t, -1.0, 1.0);
            sum += (ea - eb) * (ea - eb);
            ++used;
          }
        if (2 * used >= side * side && (!want || sum / used < *want)) want = sum / used;
      }
    const auto got = vision::depthError(t, d_t, r, d_r);
    ASSERT_EQ(got.has_value(), want.has_value()) << "trial " << trial;
    if (!want) {
      ++none;
      continue;
    }
    EXPECT_NEAR(*got, *want, 1e-12 * std::max(1.0, *want)) << "trial " << trial;
    const double thr = 1e-4;
    const auto fast = vision::depthError(t, d_t, r, d_r, thr);
    ASSERT_TRUE(fast);
    EXPECT_EQ(*fast < thr, *want < thr) << "trial " << trial;
    ++(*want < thr ? below : above);
  }
  EXPECT_GT(below, 20);  // the trials cover both verdicts and the no-overlap case
  EXPECT_GT(above, 20);
  EXPECT_GT(none, 0);
}

// The colour test's NCC written out for small patches, and through shared DFTs for larger masked
// ones (side 11 and up here), agrees with OpenCV's masked matchTemplate (TM_CCOEFF_NORMED, flat
// windows -1) on random textures, with and without a mask, at every size the pipeline uses; with
// stop_at, the same verdict. OpenCV's call leaves the mask 0 / 1 (it thresholds it in place), so
// colourError is also given such masks here.
TEST(ImageValidation, ColourErrorAgreesWithOpenCvsMatchTemplate) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  int similar = 0, different = 0;
  for (int trial = 0; trial < 120; ++trial) {
    const int side = 5 + trial % 20, region = 3 * side;
    cv::Mat img(region, region, CV_32FC3);
    for (int y = 0; y < region; ++y)
      for (int x = 0; x < region; ++x) {
        // Blocky texture; some trials with a flat band (flat windows).
        const bool flat = trial % 5 == 0 && y < region / 3;
        const float v = flat ? 0.5f : float(((x / 3) * 7 + (y / 3) * 13 + trial) % 11) / 11.f;
        img.at<cv::Vec3f>(y, x) = {v, 0.5f * v + 0.3f * u(rng), 1.f - v};
      }
    // The template: the region's centre (similar) or noise (different), sometimes masked.
    cv::Mat tmpl =
        trial % 2 ? img(cv::Rect(side, side, side, side)).clone() : cv::Mat(side, side, CV_32FC3);
    if (!(trial % 2)) cv::randu(tmpl, 0.f, 1.f);
    cv::Mat mask;
    if (trial % 3 == 0) {
      mask = cv::Mat(side, side, CV_8U, cv::Scalar(255));
      mask(cv::Rect(0, 0, side / 2, side / 2)).setTo(0);
    }
    cv::Mat t[3], r[3], res;
    cv::split(tmpl, t);
    cv::split(img, r);
    double want = 0;
    for (int c = 0; c < 3; ++c) {
      cv::matchTemplate(r[c], t[c], res, cv::TM_CCOEFF_NORMED, mask);
      cv::patchNaNs(res, -1.0);
      double lo = 0, hi = 0;
      cv::minMaxLoc(res, &lo, &hi);
      want = std::max(want, 1.0 - std::min(hi, 1.0));
    }
    const double got = vision::colourError(tmpl, img, mask);
    if (want < 1.0) {
      EXPECT_NEAR(got, want, 2e-4) << "trial " << trial << ", side " << side;
    }
    const double thr = 0.1;
    EXPECT_EQ(vision::colourError(tmpl, img, mask, thr) < thr, want < thr) << "trial " << trial;
    ++(want < thr ? similar : different);
  }
  EXPECT_GT(similar, 30);
  EXPECT_GT(different, 30);
}
