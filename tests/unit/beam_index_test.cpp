// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <set>

#include "cleanmap/core/beam_index.h"

using namespace cleanmap;

namespace {

// n returns in random directions (elevation squeezed by z_scale) at 1-60 m, drawn from rng.
std::vector<PointXYZI> randomCloud(std::mt19937& rng, int n, float z_scale) {
  std::uniform_real_distribution<float> u(-1, 1), r(1, 60);
  std::vector<PointXYZI> pts;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3f d(u(rng), u(rng), z_scale * u(rng));
    d = d.normalized() * r(rng);
    pts.push_back({d.x(), d.y(), d.z(), 0});
  }
  return pts;
}

// Every beam the index stores, decoded: the brute force's beams.
std::vector<BeamIndex::Beam> storedBeams(const BeamIndex& idx) {
  std::vector<BeamIndex::Beam> out;
  for (const auto& q : idx.beams()) out.push_back(idx.decode(q));
  return out;
}

float angle(const BeamIndex::Beam& b, const Eigen::Vector3f& dir) {
  return std::acos(std::min(1.0f, b.dir.normalized().dot(dir)));
}

}  // namespace

TEST(BeamIndex, StoresEachReturnToWithinItsSteps) {
  // Issue #16: 8-byte beams. Each stored direction is the return's to within 5e-5 rad (steps of
  // 2^-15 per component), each range its range to within half a step (2^-9 m; 2^-8 m once a
  // return lies beyond 128 m), and the index keeps every return in order of its bin.
  std::mt19937 rng(11);
  for (float far : {60.0f, 200.0f}) {
    auto pts = randomCloud(rng, 5000, 0.5f);
    pts.push_back({far, 0, 0, 0});
    const BeamIndex idx(pts, 0.0105);
    const float step = far > 128 ? 1.0f / 256 : 1.0f / 512;
    ASSERT_EQ(idx.rangeUnit(), step);
    ASSERT_EQ(idx.size(), pts.size());
    EXPECT_EQ(idx.farthest(), far);
    std::multiset<float> ranges;
    for (const auto& p : pts) ranges.insert(p.xyz().norm());
    for (const auto& q : idx.beams()) {
      const BeamIndex::Beam b = idx.decode(q);
      EXPECT_NEAR(b.dir.norm(), 1.0f, 4e-5f);
      // Some return's range lies within half a step (and float rounding) of it.
      const float tol = 0.5f * step + 1e-6f * b.range;
      auto it = ranges.lower_bound(b.range - tol);
      ASSERT_TRUE(it != ranges.end() && *it <= b.range + tol) << b.range;
    }
    // Directions: one return near the +x axis, at a known place in its bin.
    const BeamIndex one({{3.0f, 1.0f, -0.5f, 0}}, 0.01);
    const Eigen::Vector3d truth = Eigen::Vector3d(3.0, 1.0, -0.5).normalized();
    const BeamIndex::Beam b = one.decode(one.beams()[0]);
    EXPECT_LT(std::asin(b.dir.cast<double>().normalized().cross(truth).norm()), 5e-5);
    EXPECT_NEAR(b.range, std::sqrt(10.25f), 1.0f / 1024 + 1e-6f);
  }
}

TEST(BeamIndex, DropsReturnsWithNoDirectionOrAnInfiniteRange) {
  const float inf = std::numeric_limits<float>::infinity();
  const BeamIndex idx({{0, 0, 0, 0}, {inf, 0, 0, 0}, {5, 0, 0, 0}}, 0.01);
  ASSERT_EQ(idx.size(), 1u);
  EXPECT_EQ(idx.farthest(), 5.0f);
  EXPECT_EQ(idx.rangeUnit(), 1.0f / 512);
}

TEST(BeamIndex, FindsExactlyTheBeamsABruteForceFinds) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1, 1);
  auto pts = randomCloud(rng, 20000, 0.4f);
  pts.push_back({-10, 0.001f, 0, 0});  // on the azimuth seam (+-pi)
  const double radius = 0.03;
  const BeamIndex idx(pts, radius);
  EXPECT_EQ(idx.size(), pts.size());
  const auto stored = storedBeams(idx);
  for (int q = 0; q < 300; ++q) {
    Eigen::Vector3f dir =
        q == 0 ? Eigen::Vector3f(-1, -0.0005f, 0) : Eigen::Vector3f(u(rng), u(rng), 0.4f * u(rng));
    dir.normalize();
    std::multiset<float> brute, found;
    for (const auto& b : stored)
      if (angle(b, dir) <= radius) brute.insert(b.range);
    idx.forEachNear(dir, radius, [&](const BeamIndex::Beam& b) {
      if (angle(b, dir) <= radius) found.insert(b.range);
    });
    ASSERT_EQ(found, brute) << "query " << q;
  }
  EXPECT_NEAR(idx.farthest(), 60.0f, 0.5f);
}

TEST(BeamIndex, EmptyScanHasNoBeams) {
  const BeamIndex idx({}, 0.01);
  EXPECT_TRUE(idx.empty());
  int n = 0;
  idx.forEachNear(Eigen::Vector3f::UnitX(), 0.01, [&](const BeamIndex::Beam&) { ++n; });
  EXPECT_EQ(n, 0);
}

TEST(BeamIndex, FindsEveryBeamInTheConeAtAnyElevation) {
  // Directions over the whole sphere, queries up to the poles: the fast bounds (fast::asin,
  // fast::atan2, a lower bound of the cosine) still cover the cone.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1, 1);
  auto pts = randomCloud(rng, 30000, 1.0f);
  for (float z : {-1.0f, 1.0f}) pts.push_back({0.0f, 0.0f, 20 * z, 0});  // the poles
  const double radius = 0.0105;
  const BeamIndex idx(pts, radius);
  const auto stored = storedBeams(idx);
  for (int q = 0; q < 400; ++q) {
    Eigen::Vector3f dir(u(rng), u(rng), u(rng));
    if (q < 4) dir = Eigen::Vector3f(q == 2 ? 0.001f : 0.0f, q == 3 ? -0.0f : 0.0f, q % 2 ? 1 : -1);
    if (q == 4) dir = Eigen::Vector3f(-1, -0.0f, 0);
    dir.normalize();
    std::size_t brute = 0, found = 0;
    for (const auto& b : stored) brute += angle(b, dir) <= radius;
    idx.forEachNear(dir, radius,
                    [&](const BeamIndex::Beam& b) { found += angle(b, dir) <= radius; });
    ASSERT_EQ(found, brute) << "query " << q << ": " << dir.transpose();
  }
}

TEST(BeamIndex, BoxQueryFindsEveryBeamOfTheBand) {
  // forEachNearBox with the margins MovingTest::scanMass gives it finds every beam of the
  // scan-conflict check's band: within the cone across P's direction and one ring step (here
  // 2 degrees) in elevation, the offsets measured as that check does (projections on the local
  // east and up), at elevations from the horizon to near the poles.
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1, 1);
  auto pts = randomCloud(rng, 40000, 0.6f);
  const double cone = 0.0105, gap = 2.0 * M_PI / 180.0;
  const BeamIndex idx(pts, cone);
  const auto stored = storedBeams(idx);
  std::size_t in_band = 0;
  for (int q = 0; q < 400; ++q) {
    Eigen::Vector3f dir(u(rng), u(rng), 0.6f * u(rng));
    if (q == 0) dir = Eigen::Vector3f(-1, -0.0005f, 0);  // the azimuth seam
    dir.normalize();
    const Eigen::Vector3f east = Eigen::Vector3f(-dir.y(), dir.x(), 0.0f).normalized();
    const Eigen::Vector3f up = dir.cross(east);
    auto band = [&](const Eigen::Vector3f& v) {
      return v.dot(dir) > 0 && std::abs(v.dot(east)) <= cone && std::abs(v.dot(up)) <= gap;
    };
    std::size_t brute = 0, found = 0;
    for (const auto& b : stored) brute += band(b.dir.normalized());
    idx.forEachNearBox(dir, 1.01 * cone, 1.01 * gap + 2e-4,
                       [&](const BeamIndex::Beam& b) { found += band(b.dir.normalized()); });
    ASSERT_EQ(found, brute) << "query " << q << ": " << dir.transpose();
    in_band += brute;
  }
  EXPECT_GT(in_band, 1000u);  // the bands were not empty
}

TEST(BeamIndex, FastBinningEqualsTheLibmBinningOnBinEdges) {
  // Directions placed on the bins' edges (as nearly as floats allow), the azimuth seam with both
  // signs of zero, the poles, and random ones: kFast must give kExact's index bit for bit.
  const double bin = 0.0105;
  const int n_az = static_cast<int>(std::ceil(2 * M_PI / bin));
  const double step = 2 * M_PI / n_az, el0 = -0.43;
  std::vector<PointXYZI> pts;
  auto add = [&](double el, double az, float r) {
    pts.push_back({static_cast<float>(r * std::cos(el) * std::cos(az)),
                   static_cast<float>(r * std::cos(el) * std::sin(az)),
                   static_cast<float>(r * std::sin(el)), 0});
  };
  for (int e = 0; e <= 60; ++e)
    for (int a = 0; a <= n_az; ++a) add(el0 + e * step, -M_PI + a * step, 5.0f + (a % 7));
  for (float y : {0.0f, -0.0f}) pts.push_back({-12.0f, y, 0.5f, 0});
  pts.push_back({0, 0, 3, 0});
  pts.push_back({0, 0, -3, 0});
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  for (int i = 0; i < 50000; ++i) pts.push_back({40 * u(rng), 40 * u(rng), 5 * u(rng), 0});
  const BeamIndex fast(pts, bin), exact(pts, bin, BeamIndex::Binning::kExact);
  ASSERT_EQ(fast.size(), exact.size());
  EXPECT_EQ(fast.offsets(), exact.offsets());
  ASSERT_EQ(0, std::memcmp(fast.beams().data(), exact.beams().data(),
                           fast.size() * sizeof(BeamIndex::PackedBeam)));
}
