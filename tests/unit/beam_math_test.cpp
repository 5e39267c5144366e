// SPDX-License-Identifier: BSD-3-Clause
// Issue #16: the moving test's fast beam masses (fast_math.h, BeamModel::massesFast) against
// libm, and the product form of Dempster's rule in MovingTest::scanMass against the pairwise
// rule; on real scans, the fast path decides as the reference path, and the beam index's fast
// binning (fast::asin / fast::atan2 with a libm fallback at bin edges) equals libm's.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "cleanmap/core/beam_filter.h"
#include "cleanmap/core/beam_index.h"
#include "cleanmap/core/dempster_shafer.h"
#include "cleanmap/core/fast_math.h"
#include "cleanmap/core/moving_test.h"
#include "cleanmap/io/kitti.h"
#include "test_data.h"

using namespace cleanmap;

TEST(FastMath, ExpWithinItsBound) {
  // fast_math.h states 1e-7 relative on [-87, 0] (every float checked once, 8.2e-8 at most);
  // here 4 million evenly spread arguments and the ends.
  double worst = 0;
  for (int i = 0; i <= 4'000'000; ++i) {
    const float x = -87.0f * static_cast<float>(i) / 4e6f;
    const double ref = std::exp(static_cast<double>(x));
    worst = std::max(worst, std::abs(fast::expNeg(x) - ref) / ref);
  }
  EXPECT_LT(worst, 1e-7);
  EXPECT_EQ(fast::expNeg(0.0f), 1.0f);
  EXPECT_GT(fast::expNeg(-1000.0f), 0.0f);  // clamped, never a NaN or an overflow
  EXPECT_LT(fast::expNeg(-1000.0f), 1e-37f);
}

TEST(FastMath, ErfcWithinItsBound) {
  double worst_abs = 0, worst_rel = 0;
  for (int i = -4'000'000; i <= 4'000'000; ++i) {
    const float x = 9.0f * static_cast<float>(i) / 4e6f;
    const double ref = std::erfc(static_cast<double>(x));
    const double err = std::abs(fast::erfc(x) - ref);
    worst_abs = std::max(worst_abs, err);
    if (std::abs(x) <= 4.0f) worst_rel = std::max(worst_rel, err / ref);
  }
  EXPECT_LT(worst_abs, 6e-7);
  EXPECT_LT(worst_rel, 2e-6);
}

TEST(FastMath, AsinAndAtan2WithinTheirBounds) {
  // fast_math.h states 2e-7 and 3e-7 rad; BeamIndex assumes kAngleError (1e-6) for both.
  double worst_asin = 0, worst_atan2 = 0;
  for (int i = -4'000'000; i <= 4'000'000; ++i) {
    const float s = static_cast<float>(i) / 4e6f;
    worst_asin = std::max(worst_asin, std::abs(fast::asin(s) - std::asin(double(s))));
  }
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ua(-M_PI, M_PI), ur(1e-3, 100.0);
  for (int i = 0; i < 4'000'000; ++i) {
    const double a = ua(rng), r = ur(rng);
    float x = static_cast<float>(r * std::cos(a)), y = static_cast<float>(r * std::sin(a));
    if (i % 101 == 0) x = 0;  // the axes
    if (i % 103 == 0) y = 0;
    if (x == 0 && y == 0) continue;
    worst_atan2 =
        std::max(worst_atan2, std::abs(fast::atan2(y, x) - std::atan2(double(y), double(x))));
  }
  EXPECT_LT(worst_asin, 2e-7);
  EXPECT_LT(worst_atan2, 3e-7);
  EXPECT_LT(std::max(worst_asin, worst_atan2) * 3, BeamIndex::kAngleError);
  EXPECT_EQ(fast::asin(1.0f), static_cast<float>(M_PI / 2));
  EXPECT_EQ(fast::atan2(0.0f, 1.0f), 0.0f);
}

TEST(BeamIndex, FastBinningEqualsTheLibmBinningOnRealScans) {
  // Every labelled set, first, middle and last scan: the same index, bit for bit.
  for (const char* set : {"kitti_city", "kitti_highway", "kitti_residential"}) {
    CLEANMAP_REQUIRE_DATASET(set);
    const auto seq = io::KittiSequence::open(test::dataDir() + "/" + set);
    const double bin = MovingTest(DsParams{}).searchRadius();
    for (std::size_t i : {std::size_t{0}, seq.size() / 2, seq.size() - 1}) {
      const auto scan = seq.loadScan(i);
      const BeamIndex fast(scan.points, bin), exact(scan.points, bin, BeamIndex::Binning::kExact);
      ASSERT_EQ(fast.size(), exact.size()) << set << " scan " << i;
      ASSERT_GT(fast.size(), 50000u);
      EXPECT_EQ(fast.offsets(), exact.offsets()) << set << " scan " << i;
      ASSERT_EQ(0, std::memcmp(fast.beams().data(), exact.beams().data(),
                               fast.size() * sizeof(BeamIndex::PackedBeam)))
          << set << " scan " << i;
    }
  }
}

TEST(FastMath, BeamMassesAgreeWithLibmAndDoNotDependOnTheBatch) {
  // Every r from far in front of the return to r_far behind it, every angle in the cone.
  const DsParams p;
  const ds::BeamModel m(p);
  const float r2max = static_cast<float>(std::pow(p.search_lambdas * p.lambda_theta, 2));
  std::mt19937 rng(16);
  std::uniform_real_distribution<float> ur(-3.0f, 9.1f), ut(0.0f, r2max);
  constexpr int kB = ds::BeamModel::kBatch;
  double worst = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    alignas(64) float r[kB], t2[kB], e[kB], o[kB], e_ref[kB], o_ref[kB];
    for (int k = 0; k < kB; ++k) {
      r[k] = ur(rng);
      t2[k] = ut(rng);
    }
    const int n = 1 + trial % kB;
    m.massesFast(r, t2, n, e, o);
    m.massesReference(r, t2, n, e_ref, o_ref);
    for (int k = 0; k < n; ++k) {
      worst =
          std::max({worst, std::abs(double(e[k]) - e_ref[k]), std::abs(double(o[k]) - o_ref[k])});
      // The same beam alone in a batch gives the same bits (lanes are independent).
      alignas(64) float r1[kB] = {r[k]}, t1[kB] = {t2[k]}, e1[kB], o1[kB];
      if (trial % 97 == 0) {
        m.massesFast(r1, t1, 1, e1, o1);
        EXPECT_EQ(e1[0], e[k]);
        EXPECT_EQ(o1[0], o[k]);
      }
    }
  }
  EXPECT_LT(worst, 2e-6);
}

namespace {

// A wall 10 m ahead with a gap, seen by a 0.1 deg x 0.2 deg grid of beams.
std::vector<PointXYZI> wallWithGap() {
  std::vector<PointXYZI> pts;
  for (int iy = -60; iy <= 60; ++iy)
    for (int iz = -20; iz <= 20; ++iz) {
      const double ay = iy * 0.0017, az = iz * 0.0035;
      const double range = (iy > 5 && iy < 25) ? 30.0 : 10.0;  // the gap: beams hit far behind
      const Eigen::Vector3d d(std::cos(az) * std::cos(ay), std::cos(az) * std::sin(ay),
                              std::sin(az));
      const Eigen::Vector3f q = (range * d).cast<float>();
      pts.push_back({q.x(), q.y(), q.z(), 0.5f});
    }
  return pts;
}

struct LongMass {
  long double e = 0, o = 0, u = 1;
};

LongMass combineLong(const LongMass& a, const ds::Mass& b) {  // ds::combine, in long double
  const long double inv = 1.0L / (1.0L - (a.o * b.e + a.e * b.o));
  return {(a.e * b.e + a.e * b.u + a.u * b.e) * inv, (a.o * b.o + a.o * b.u + a.u * b.o) * inv,
          a.u * b.u * inv};
}

}  // namespace

TEST(MovingTest, VectorisedBeamFilterGivesTheScalarBits) {
  // detail::filterBeams (vector lanes, no contraction) against the scalar Eigen expressions of
  // MovingTest's reference path, bit for bit, for every run length (vector body and remainders).
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1), range(0.5f, 80);
  constexpr int kMax = 40;
  std::vector<BeamIndex::PackedBeam> beams(kMax);
  // Two range steps: the default 2^-9 m and 2^-8 m, an index whose farthest return is 200 m.
  const BeamIndex near_index({{10, 0, 0, 0}}, 0.01), far_index({{200, 0, 0, 0}}, 0.01);
  ASSERT_EQ(near_index.rangeUnit(), 1.0f / 512);
  ASSERT_EQ(far_index.rangeUnit(), 1.0f / 256);
  auto quantise = [](float c) { return static_cast<int16_t>(std::lrint(c * 32767.0f)); };
  for (int trial = 0; trial < 3000; ++trial) {
    const BeamIndex& index = trial % 2 ? far_index : near_index;
    Eigen::Vector3f dir(u(rng), u(rng), 0.3f * u(rng));
    dir.normalize();
    const float df = range(rng), r2max = 1e-4f, r_far = 3.0f;
    for (auto& b : beams) {  // around dir, some in the cone, some behind the sensor
      const Eigen::Vector3f d =
          (trial % 5 == 0 ? Eigen::Vector3f(u(rng), u(rng), u(rng))
                          : Eigen::Vector3f(dir + 0.02f * Eigen::Vector3f(u(rng), u(rng), u(rng))))
              .normalized();
      b = {quantise(d.x()), quantise(d.y()), quantise(d.z()),
           static_cast<uint16_t>(range(rng) / index.rangeUnit())};
    }
    const int m = 1 + trial % kMax;
    float r[kMax], t2[kMax];
    int32_t keep[kMax];
    detail::filterBeams(beams.data(), m, index.rangeUnit(), dir.x(), dir.y(), dir.z(), df, r2max,
                        r_far, r, t2, keep);
    for (int k = 0; k < m; ++k) {
      const BeamIndex::Beam q = index.decode(beams[static_cast<std::size_t>(k)]);
      const float theta2 = dir.cross(q.dir).squaredNorm();
      const float rr = df * std::sqrt(1.0f - theta2) - q.range;
      const int32_t kk = (theta2 <= r2max) & (dir.dot(q.dir) > 0.0f) & (rr <= r_far);
      ASSERT_EQ(0, std::memcmp(&t2[k], &theta2, sizeof theta2)) << trial << " " << k;
      ASSERT_EQ(0, std::memcmp(&r[k], &rr, sizeof rr)) << trial << " " << k;
      ASSERT_EQ(keep[k], kk) << trial << " " << k;
    }
  }
}

TEST(MovingTest, ProductFormEqualsThePairwiseRule) {
  // scanMass multiplies commonalities instead of folding Dempster's rule beam by beam (Eq. 6);
  // both are the same normalised mass. Points on the wall, in the gap and at its edges, where
  // beams conflict: there each pairwise step divides by a small 1 - K and loses digits (5e-8
  // in double), so the pairwise rule is folded in long double here; the forms then agree to
  // 3e-11 (a wrong rule would be off by 1e-2 or more).
  DsParams p;
  p.scan_conflict = 1.0;  // the raw combination, without the scan-conflict rule
  const ds::BeamModel model(p);
  const MovingTest t(p, BeamMath::kReference);
  const auto scan = wallWithGap();
  const BeamIndex idx(scan, t.searchRadius());
  const WindowScan w{&idx, Eigen::Isometry3d::Identity()};
  int both = 0;
  for (int iy = -30; iy <= 40; ++iy)
    for (double range : {9.0, 10.0, 10.1, 12.0}) {
      const double ay = iy * 0.00085;
      const Eigen::Vector3d at = range * Eigen::Vector3d(std::cos(ay), std::sin(ay), 0.001);
      LongMass pairwise;
      const Eigen::Vector3f dir = at.normalized().cast<float>();
      const float df = static_cast<float>(at.norm());
      idx.forEachNear(dir, t.searchRadius(), [&](const BeamIndex::Beam& q) {
        const float theta2 = dir.cross(q.dir).squaredNorm();
        if (theta2 > float(t.searchRadius() * t.searchRadius()) || dir.dot(q.dir) <= 0) return;
        const float r = df * std::sqrt(1.0f - theta2) - q.range;
        if (r > std::sqrt(2.0 * model.s1 * 40.0)) return;
        pairwise = combineLong(pairwise, model.beamFloat(r, theta2));
      });
      double d = 0;
      const ds::Mass product = t.scanMass(at, w, &d, nullptr);
      EXPECT_NEAR(product.e, static_cast<double>(pairwise.e), 1e-9) << at.transpose();
      EXPECT_NEAR(product.o, static_cast<double>(pairwise.o), 1e-9) << at.transpose();
      EXPECT_NEAR(product.u, static_cast<double>(pairwise.u), 1e-9) << at.transpose();
      both += pairwise.e > 0.5 || pairwise.o > 0.5;
    }
  EXPECT_GT(both, 100);  // decided masses, not just unknown
}

TEST(MovingTest, FastBeamMathDecidesAsLibmOnRealScans) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  // Scan 8 of the highway against the 16 scans around it (given poses), every 10th point
  // above the road: the two paths' scan masses and decisions.
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  const DsParams p;
  const MovingTest fast(p, BeamMath::kFast), ref(p, BeamMath::kReference);
  std::vector<Scan> scans;
  std::vector<BeamIndex> idx;
  for (std::size_t i = 0; i <= 16; ++i) scans.push_back(seq.loadScan(i));
  for (const auto& s : scans) idx.emplace_back(s.points, fast.searchRadius());
  // Given poses, then the pose error of estimated ones (issue #11: 1 % of the path between the
  // scans), under which a scan that votes empty is checked for returns at P's range over a wider
  // cone (scanMassAt; filterBeams' runs on the fast path, the scalar loop on the reference).
  std::size_t emptied_by[2] = {0, 0};  // scan votes made unknown by the scan-conflict rule
  for (const double relative_error : {0.0, 0.01}) {
    std::vector<WindowScan> w;
    for (std::size_t i = 0; i < scans.size(); ++i) {
      if (i == 8) continue;
      double path = 0;
      for (std::size_t a = std::min<std::size_t>(i, 8); a < std::max<std::size_t>(i, 8); ++a)
        path += (seq.poses()[a + 1].translation() - seq.poses()[a].translation()).norm();
      const double noise = relative_error * path;
      w.push_back({&idx[i], seq.poses()[i].inverse(), noise * noise});
    }
    std::size_t n = 0, moving = 0, differ = 0, emptied = 0;
    double worst = 0;
    for (std::size_t j = 0; j < scans[8].points.size(); j += 10) {
      const auto& q = scans[8].points[j];
      if (q.z < -1.4 || q.xyz().norm() > 50) continue;
      const Eigen::Vector3d at = seq.poses()[8] * q.xyz().cast<double>();
      const bool a = fast.isMoving(at, w, nullptr), b = ref.isMoving(at, w, nullptr);
      differ += a != b;
      moving += b;
      ++n;
      if (j % 50 == 0)
        for (const auto& s : w) {
          double d = 0;
          MovingTestStats sf, sr;
          const ds::Mass mf = fast.scanMass(at, s, &d, &sf), mr = ref.scanMass(at, s, &d, &sr);
          worst = std::max({worst, std::abs(mf.e - mr.e), std::abs(mf.o - mr.o)});
          differ += sf.conflicting_scans != sr.conflicting_scans;
          emptied += sr.conflicting_scans;
        }
    }
    SCOPED_TRACE(relative_error);
    ASSERT_GT(n, 5000u);
    EXPECT_GT(moving, n / 100);  // moving cars are in the sample: both outcomes occur
    EXPECT_LE(differ, n / 10000) << differ << " of " << n;  // measured: 0
    EXPECT_LT(worst, 1e-4);
    emptied_by[relative_error > 0] = emptied;
  }
  // The wider cone took empty votes away (measured: 409 -> 550), the same ones on both paths.
  EXPECT_GT(emptied_by[1], emptied_by[0] + 50) << emptied_by[0] << " -> " << emptied_by[1];
}
