// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <random>
#include <set>

#include "cleanmap/core/beam_index.h"

using namespace cleanmap;

TEST(BeamIndex, FindsExactlyTheBeamsABruteForceFinds) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1, 1), r(1, 60);
  std::vector<PointXYZI> pts;
  for (int i = 0; i < 20000; ++i) {
    Eigen::Vector3f d(u(rng), u(rng), 0.4f * u(rng));
    d = d.normalized() * r(rng);
    pts.push_back({d.x(), d.y(), d.z(), 0});
  }
  pts.push_back({-10, 0.001f, 0, 0});  // on the azimuth seam (+-pi)
  const double radius = 0.03;
  const BeamIndex idx(pts, radius);
  EXPECT_EQ(idx.size(), pts.size());
  for (int q = 0; q < 300; ++q) {
    Eigen::Vector3f dir =
        q == 0 ? Eigen::Vector3f(-1, -0.0005f, 0) : Eigen::Vector3f(u(rng), u(rng), 0.4f * u(rng));
    dir.normalize();
    std::multiset<float> brute, found;
    for (const auto& p : pts) {
      const Eigen::Vector3f v = p.xyz().normalized();
      if (std::acos(std::min(1.0f, v.dot(dir))) <= radius) brute.insert(p.xyz().norm());
    }
    idx.forEachNear(dir, radius, [&](const BeamIndex::Beam& b) {
      if (std::acos(std::min(1.0f, b.dir.dot(dir))) <= radius) found.insert(b.range);
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
