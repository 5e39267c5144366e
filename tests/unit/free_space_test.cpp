// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2e: the free-space accumulator that cleans the map: what a beam marks, the scan-conflict
// rule, the two policies, and merging chunks (sums, minima, maxima: any order, same result).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "cleanmap/core/free_space.h"
#include "cleanmap/core/grazing.h"
#include "cleanmap/core/sanitized.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

using namespace cleanmap;

namespace {

// A scan of one ring of beams in the horizontal plane, all returning at `range`, plus `extra`.
std::vector<PointXYZI> ring(float range, std::vector<PointXYZI> extra = {}) {
  std::vector<PointXYZI> pts = std::move(extra);
  for (int a = 0; a < 2000; ++a) {
    const float t = 2.f * float(M_PI) * float(a) / 2000.f;
    pts.push_back({range * std::cos(t), range * std::sin(t), 0.f, 0.f});
  }
  return pts;
}

MapParams params() {
  MapParams p;
  p.free_ratio = 0;
  return p;
}

Eigen::Isometry3d at(double x) {
  return Eigen::Isometry3d(Eigen::Translation3d(x, 0, 0));
}

}  // namespace

TEST(FreeSpace, ABeamMarksTheSpaceBeforeItsReturnNotAtIt) {
  FreeSpaceMap fs(params());
  fs.insertScan(ring(20.f), at(0), 0);
  EXPECT_EQ(fs.evidence({10.f, 0.f, 0.f}).count, 1);  // passed through
  EXPECT_EQ(fs.evidence({10.f, 0.f, 0.f}).first, 0);
  EXPECT_EQ(fs.evidence({20.f, 0.f, 0.f}).count, 0);    // the return itself
  EXPECT_EQ(fs.evidence({19.75f, 0.f, 0.f}).count, 0);  // within the margin
  EXPECT_EQ(fs.evidence({25.f, 0.f, 0.f}).count, 0);    // behind it: unseen
  EXPECT_EQ(fs.evidence({0.5f, 0.f, 0.f}).count, 0);    // inside min_range
}

TEST(FreeSpace, AScanDoesNotSeeEmptyWhereItReturnsFrom) {
  // A post at 8 m in front of a wall at 20 m: the beam to the wall behind the post's side passes
  // through the post's voxel (scan-conflict rule: the scan returns from it, so it is not empty).
  FreeSpaceMap fs(params());
  fs.insertScan(ring(20.f, {{8.05f, 0.f, 0.f, 0.f}}), at(0), 0);
  EXPECT_EQ(fs.evidence({8.05f, 0.f, 0.f}).count, 0);
  EXPECT_EQ(fs.evidence({8.05f, 0.f, 0.f}).hits, 1);
}

TEST(FreeSpace, ScansCountOnceAndPoliciesDecide) {
  MapParams p = params();
  FreeSpaceMap fs(p);
  // A car at x = 10 in scan 5 only; scans 0..4 and 6..9 see through its place to a wall at 20.
  for (int k = 0; k < 10; ++k)
    fs.insertScan(k == 5 ? ring(20.f, {{10.05f, 0.f, 0.f, 0.f}}) : ring(20.f), at(0), k);
  const FreeEvidence e = fs.evidence({10.05f, 0.f, 0.f});
  EXPECT_EQ(e.count, 9);  // many beams of a scan cross a voxel: it counts scans
  EXPECT_EQ(e.hits, 1);
  EXPECT_EQ(e.first, 0);
  EXPECT_EQ(e.last, 9);
  p.policy = MapPolicy::kTransient;
  EXPECT_TRUE(removedByPolicy(e, 5, p));
  p.policy = MapPolicy::kMoving;
  EXPECT_TRUE(removedByPolicy(e, 5, p));   // empty before and after: it came and went
  EXPECT_FALSE(removedByPolicy(e, 0, p));  // a point of scan 0: never empty before it
  EXPECT_FALSE(removedByPolicy(e, 9, p));  // ... of scan 9: never empty after it
  p.policy = MapPolicy::kTransient;
  EXPECT_TRUE(removedByPolicy(e, 0, p));  // a parked car that left: transient removes it
  p.min_free_scans = 10;
  EXPECT_FALSE(removedByPolicy(e, 5, p));  // not enough evidence
  p.min_free_scans = 2;
  p.free_ratio = 10;                      // 9 empty scans < 10 x 1 hit ...
  EXPECT_TRUE(removedByPolicy(e, 5, p));  // ... but 5 saw it empty before its return (arrived)
  p.arrived_scans = 6;
  EXPECT_FALSE(removedByPolicy(e, 5, p));
  p.clean = false;
  p.free_ratio = 0;
  EXPECT_FALSE(removedByPolicy(e, 5, p));
}

TEST(FreeSpace, ChunksMergeInAnyOrderToTheWholeRun) {
  const MapParams p = params();
  std::vector<std::vector<PointXYZI>> scans;
  for (int k = 0; k < 6; ++k)
    scans.push_back(ring(15.f + float(k), {{6.f + float(k), 1.f, 0.2f, 0.f}}));
  FreeSpaceMap whole(p), a(p), b(p);
  for (int k = 0; k < 6; ++k) {
    whole.insertScan(scans[k], at(0.7 * k), k);
    (k < 3 ? a : b).insertScan(scans[k], at(0.7 * k), k);
  }
  FreeSpaceMap ab(a), ba(b);
  ab.merge(b);
  ba.merge(a);
  FreeSpaceMap a_again(p);  // the copy merged into is its own: `a` is as it was
  for (int k = 0; k < 3; ++k) a_again.insertScan(scans[k], at(0.7 * k), k);
  // Voxel counters are allocated by 2^3 sub-blocks where written: a ring leaves most unwritten.
  EXPECT_LT(whole.subBlocks(), whole.blocks() * 64 / 2);
  int checked = 0;
  for (float x = -20; x <= 25; x += 0.1f)
    for (float y = -3; y <= 3; y += 0.5f) {
      const Eigen::Vector3f q(x, y, 0.05f);
      const FreeEvidence w = whole.evidence(q), e1 = ab.evidence(q), e2 = ba.evidence(q);
      ASSERT_EQ(w.count, e1.count);
      ASSERT_EQ(w.count, e2.count);
      ASSERT_EQ(w.hits, e1.hits);
      ASSERT_EQ(w.first, e2.first);
      ASSERT_EQ(w.last, e1.last);
      ASSERT_EQ(w.emptied_between, e1.emptied_between);
      ASSERT_EQ(w.emptied_between, e2.emptied_between);
      ASSERT_EQ(a.evidence(q), a_again.evidence(q));
      checked += w.count > 0;
    }
  EXPECT_GT(checked, 1000);
}

TEST(FreeSpace, ALookupThatRemembersItsBlockAnswersAsEvidenceDoes) {
  // Points in a row (the same block, then the next), jumps between blocks, and points where the
  // map has no block at all, in both orders: the remembered block never answers for another.
  FreeSpaceMap m(params());
  for (int k = 0; k < 4; ++k) m.insertScan(ring(12.f + float(k)), at(0.5 * k), k);
  std::vector<Eigen::Vector3f> qs;
  for (float x = -30; x <= 30; x += 0.07f) qs.emplace_back(x, 0.3f, 0.05f);
  for (int i = 0; i < 400; ++i)  // scattered, some far outside
    qs.emplace_back(float((i * 37) % 120) - 60.f, float((i * 53) % 90) - 45.f, 0.05f);
  for (int pass = 0; pass < 2; ++pass) {
    FreeSpaceMap::Lookup look(m);
    int seen = 0, none = 0;
    for (const auto& q : qs) {
      const FreeEvidence e = m.evidence(q);
      ASSERT_EQ(look(q), e) << q.transpose();
      seen += e.count > 0;
      none += e.count == 0 && e.hits == 0;
    }
    EXPECT_GT(seen, 300);
    EXPECT_GT(none, 100);
    std::reverse(qs.begin(), qs.end());
  }
}

TEST(FreeSpace, SpaceOnlyEmptyAfterItsLastReturnWasVacated) {
  // A truck side at x = 10 returns in scans 0..19, then leaves: scans 20..25 see through to the
  // wall. Fewer empty scans than hits (6 < 0.5 x 20), but every scan after the last return saw it
  // empty for 6 >= vacated_scans scans: it goes. Foliage at the same place (hit in 30 scans,
  // empty in 10 others among them, the last one a scan after the last hit) stays.
  MapParams p = params();
  p.free_ratio = 0.5;
  p.vacated_scans = 5;
  const PointXYZI side{10.05f, 0.f, 0.f, 0.f};
  FreeSpaceMap truck(p), foliage(p);
  for (int k = 0; k < 26; ++k) truck.insertScan(k < 20 ? ring(20.f, {side}) : ring(20.f), at(0), k);
  for (int k = 0; k < 40; ++k)
    foliage.insertScan(k % 4 == 3 ? ring(20.f) : ring(20.f, {side}), at(0), k);
  const FreeEvidence t = truck.evidence(side.xyz()), f = foliage.evidence(side.xyz());
  EXPECT_EQ(t.count, 6);
  EXPECT_EQ(t.hits, 20);
  EXPECT_EQ(t.last_hit, 19);
  EXPECT_EQ(f.count, 10);
  EXPECT_EQ(f.last_hit, 38);
  EXPECT_TRUE(removedByPolicy(t, 3, p));
  EXPECT_FALSE(removedByPolicy(f, 3, p));
  p.vacated_scans = 0;  // off: the hit ratio alone keeps the truck
  EXPECT_FALSE(removedByPolicy(t, 3, p));
  p.vacated_scans = 7;  // 6 scans of empty space are not enough
  EXPECT_FALSE(removedByPolicy(t, 3, p));
}

TEST(FreeSpace, SpaceEmptyBeforeItsFirstReturnWasArrivedInto) {
  // A slow truck's front pushes into the lane: scans 0..5 see through x = 10 to the wall, scans
  // 6..35 return from the truck's side there. Fewer empty scans than hits (6 < 0.5 x 30) and the
  // truck is still there at the end, but 6 >= arrived_scans scans saw the place empty before its
  // first return: something came. A wall first seen at scan 6 (nothing passed through it before)
  // and foliage (seen through now and then, from the first scan on) stay. Cut into chunks inside
  // the empty run, the merged evidence is the whole run's, in either order of merging.
  MapParams p = params();
  p.free_ratio = 0.5;
  p.vacated_scans = 5;
  p.arrived_scans = 5;
  const PointXYZI side{10.05f, 0.f, 0.f, 0.f};
  const auto truck = [&](int k) { return k < 6 ? ring(20.f) : ring(20.f, {side}); };
  FreeSpaceMap whole(p), wall(p), foliage(p), a(p), b(p);
  for (int k = 0; k < 36; ++k) {
    whole.insertScan(truck(k), at(0), k);
    (k < 3 ? a : b).insertScan(truck(k), at(0), k);
    if (k >= 6) wall.insertScan(ring(20.f, {side}), at(0), k);
    foliage.insertScan(k % 4 == 3 ? ring(20.f) : ring(20.f, {side}), at(0), k);
  }
  const FreeEvidence t = whole.evidence(side.xyz());
  EXPECT_EQ(t.count, 6);
  EXPECT_EQ(t.hits, 30);
  EXPECT_EQ(t.lead, 6);
  EXPECT_TRUE(removedByPolicy(t, 20, p));
  EXPECT_FALSE(removedByPolicy(wall.evidence(side.xyz()), 20, p));
  EXPECT_FALSE(removedByPolicy(foliage.evidence(side.xyz()), 20, p));
  FreeSpaceMap ab(a), ba(b);
  ab.merge(b);
  ba.merge(a);
  EXPECT_EQ(ab.evidence(side.xyz()), t);
  EXPECT_EQ(ba.evidence(side.xyz()), t);
  p.arrived_scans = 0;  // off: the hit ratio keeps the truck's side
  EXPECT_FALSE(removedByPolicy(t, 20, p));
  p.arrived_scans = 7;  // 6 scans of empty space are not enough
  EXPECT_FALSE(removedByPolicy(t, 20, p));
  p.arrived_scans = 5;
  p.policy = MapPolicy::kMoving;  // it came and stayed: not "came and went"
  EXPECT_FALSE(removedByPolicy(t, 20, p));
  EXPECT_FALSE(removedByPolicy(t, 3, p));  // nor for a point of a scan before the truck came
}

TEST(FreeSpace, SpaceEmptiedBetweenTwoReturnsWasVacated) {
  // A queue passing a standing sensor: car sides at x = 10 return in scans 0..9, the gap to the
  // next car is seen through in scans 10..13, the next car returns in 14..23. Fewer empty scans
  // than hits (4 < 0.5 x 20), but a run of 4 >= between_scans lay between two returns: the voxel
  // goes. Foliage hit 3 scans in 4 never stays empty that long, and a gap of 2 scans is not
  // enough. Cut into chunks inside the gap, the merged runs (2 + 2) find it as the whole run
  // does, in either order of merging. The rule is its own: vacated_scans (the run after the last
  // return) off leaves it on.
  MapParams p = params();
  p.free_ratio = 0.5;
  p.vacated_scans = 5;
  p.between_scans = 3;
  const PointXYZI side{10.05f, 0.f, 0.f, 0.f};
  auto queue = [&](int gap, int k) {
    return k < 10 || k >= 10 + gap ? ring(20.f, {side}) : ring(20.f);
  };
  // The queue with a gap of 4 scans, whole and cut into two chunks at scan 12 (inside the gap).
  auto insert = [&](FreeSpaceMap& whole, FreeSpaceMap& first, FreeSpaceMap& second) {
    for (int k = 0; k < 24; ++k) {
      whole.insertScan(queue(4, k), at(0), k);
      (k < 12 ? first : second).insertScan(queue(4, k), at(0), k);
    }
  };
  FreeSpaceMap whole(p), short_gap(p), foliage(p), a(p), b(p);
  insert(whole, a, b);
  for (int k = 0; k < 24; ++k) short_gap.insertScan(queue(2, k), at(0), k);
  for (int k = 0; k < 40; ++k)
    foliage.insertScan(k % 4 == 3 ? ring(20.f) : ring(20.f, {side}), at(0), k);
  const FreeEvidence w = whole.evidence(side.xyz());
  EXPECT_EQ(w.count, 4);
  EXPECT_EQ(w.hits, 20);
  EXPECT_TRUE(w.emptied_between);
  EXPECT_TRUE(removedByPolicy(w, 3, p));
  EXPECT_FALSE(short_gap.evidence(side.xyz()).emptied_between);
  EXPECT_FALSE(removedByPolicy(short_gap.evidence(side.xyz()), 3, p));
  EXPECT_FALSE(foliage.evidence(side.xyz()).emptied_between);
  EXPECT_FALSE(removedByPolicy(foliage.evidence(side.xyz()), 3, p));
  EXPECT_FALSE(a.evidence(side.xyz()).emptied_between);  // 2 empty scans each side of the cut
  EXPECT_FALSE(b.evidence(side.xyz()).emptied_between);
  FreeSpaceMap ab(a), ba(b);
  ab.merge(b);
  ba.merge(a);
  EXPECT_TRUE(ab.evidence(side.xyz()).emptied_between);
  EXPECT_TRUE(ba.evidence(side.xyz()).emptied_between);
  p.vacated_scans = 0;  // the run after the last return off: the run between two still counts
  EXPECT_TRUE(removedByPolicy(w, 3, p));
  p.between_scans = 0;  // off
  EXPECT_FALSE(removedByPolicy(w, 3, p));
  p.between_scans = 5;  // a longer run needed: the gap of 4 is kept (at insertion and merging)
  FreeSpaceMap strict(p), sa(p), sb(p);
  insert(strict, sa, sb);
  sa.merge(sb);
  EXPECT_FALSE(strict.evidence(side.xyz()).emptied_between);
  EXPECT_FALSE(sa.evidence(side.xyz()).emptied_between);
}

TEST(FreeSpace, AScanSeesNothingEmptyNextToItsOwnStaticReturns) {
  // A post at (8.05, 0): the ring's beams pass its side through the neighbouring voxel (y in
  // [0.2, 0.4)). With hit_inflate 0 that voxel is seen empty by the post's own scan; with 0.2 m it
  // is not, unless the post's return is flagged moving (a slow mover's neighbourhood is what it
  // leaves empty next).
  const PointXYZI post{8.05f, 0.f, 0.f, 0.f};
  const Eigen::Vector3f beside(8.05f, 0.25f, 0.f);
  const auto pts = ring(20.f, {post});
  MapParams p = params();
  p.hit_inflate = 0;
  FreeSpaceMap plain(p);
  plain.insertScan(pts, at(0), 0);
  EXPECT_EQ(plain.evidence(beside).count, 1);
  p.hit_inflate = 0.2;
  FreeSpaceMap inflated(p), flagged(p);
  inflated.insertScan(pts, at(0), 0);
  EXPECT_EQ(inflated.evidence(beside).count, 0);
  EXPECT_EQ(inflated.evidence({10.f, 0.f, 0.f}).count, 1);  // the beam behind the post still marks
  std::vector<uint8_t> moving(pts.size(), 0);
  moving[0] = 1;  // the post
  flagged.insertScan(pts, at(0), 0, &moving);
  EXPECT_EQ(flagged.evidence(beside).count, 1);
  moving.pop_back();
  EXPECT_THROW(flagged.insertScan(pts, at(0), 1, &moving), std::invalid_argument);
}

namespace {
// A lidar of `rings` rings evenly over -15..15 degrees and `columns` columns, every beam returning
// from a cylinder wall `range` away horizontally; no returns over azimuths in [blocked_from, pi).
std::vector<PointXYZI> lidar(int columns, int rings, float range, float blocked_from = 10.f) {
  std::vector<PointXYZI> pts;
  for (int c = 0; c < columns; ++c) {
    const float az = -float(M_PI) + 2.f * float(M_PI) * (float(c) + 0.5f) / float(columns);
    if (az >= blocked_from) continue;
    for (int r = 0; r < rings; ++r) {
      const float el = float(M_PI / 180.0) * (-15.f + 30.f * float(r) / float(rings - 1));
      pts.push_back({range * std::cos(az), range * std::sin(az), range * std::tan(el), 0.f});
    }
  }
  return pts;
}
}  // namespace

TEST(FreeSpace, AzimuthBinIsTheLidarsOwnStepWhereItIsWiderThanTheBeamSpacing) {
  const double spacing = MapParams{}.beam_spacing;
  // Denser than the bins (an HDL-64E's 0.09 degrees): the configured spacing, bit for bit.
  EXPECT_EQ(freeSpaceAzimuthBin(lidar(4000, 16, 12.f), spacing), spacing);
  EXPECT_EQ(freeSpaceAzimuthBin(lidar(4000, 16, 12.f), 0.0), 0.0);
  // An Ouster at 1024 columns, a VLP-16 at 0.2 and at 0.4 degrees: at least their step (every
  // bin holds a beam of each ring), at most 15 % over it; a quarter of the view blocked (the
  // vehicle, an empty sector) does not change it.
  for (const int columns : {1024, 1800, 900}) {
    const double step = 2 * M_PI / columns;
    const double whole = freeSpaceAzimuthBin(lidar(columns, 16, 12.f), spacing);
    EXPECT_GE(whole, step) << columns << " columns";
    EXPECT_LE(whole, 1.15 * step) << columns << " columns";
    EXPECT_NEAR(freeSpaceAzimuthBin(lidar(columns, 16, 12.f, float(M_PI / 2)), spacing), whole,
                0.01 * whole)
        << columns << " columns, a quarter blocked";
  }
}

TEST(FreeSpace, ASparseLidarSeesEmptyTheSpaceNearItAsEveryBeamWould) {
  // Near the sensor the walk leaves out beams whose neighbours cross the same voxels (DESIGN §2e).
  // For an Ouster at 1024 columns that must not leave voxels unseen: every voxel 2-5 m away that
  // the walk of every beam from min_range (beam_spacing 0) sees empty is seen empty.
  const auto scan = lidar(1024, 16, 12.f);
  MapParams all = params();
  all.beam_spacing = 0;
  FreeSpaceMap thinned(params()), every(all);
  thinned.insertScan(scan, at(0), 0);
  every.insertScan(scan, at(0), 0);
  std::size_t seen = 0, kept = 0;
  const float v = static_cast<float>(all.voxel);
  for (float x = -5.f + v / 2; x < 5.f; x += v)
    for (float y = -5.f + v / 2; y < 5.f; y += v)
      for (float z = -1.5f + v / 2; z < 1.5f; z += v) {
        const float rh = std::hypot(x, y);
        if (rh < 2.f || rh > 5.f || every.evidence({x, y, z}).count == 0) continue;
        ++seen;
        kept += thinned.evidence({x, y, z}).count > 0;
      }
  ASSERT_GT(seen, 1000u);
  EXPECT_GE(double(kept) / double(seen), 0.97) << kept << " of " << seen;
  EXPECT_LT(thinned.voxelsMarked(), every.voxelsMarked());  // it still walks less
  EXPECT_GT(thinned.azimuthBinMin(), 2 * M_PI / 1024);
}

namespace {
// A box 8-12 m ahead (top 0.19 m under the sensor, 2 m wide) before a wall at 20 m, seen by rings
// at `elev` degrees over +-3 degrees of azimuth (0.1 degree steps): each beam's first hit.
std::vector<PointXYZI> roofScene() {
  const std::vector<double> elev{2, 1, 0.5, 0, -0.5, -0.85, -1.0, -1.2, -1.4, -1.7, -2.0, -2.5, -3};
  std::vector<PointXYZI> pts;
  for (double e : elev)
    for (int c = -30; c <= 30; ++c) {
      const double a = c * 0.1 * M_PI / 180, el = e * M_PI / 180;
      const Eigen::Vector3d d(std::cos(el) * std::cos(a), std::cos(el) * std::sin(a), std::sin(el));
      double t = 20 / d.x();  // the wall
      if (d.z() < 0) {
        const double top = -0.19 / d.z(), front = 8 / d.x();
        if (d.x() * top >= 8 && d.x() * top <= 12)
          t = top;  // the roof
        else if (d.z() * front <= -0.19)
          t = front;  // its front
      }
      const Eigen::Vector3d p = t * d;
      pts.push_back({float(p.x()), float(p.y()), float(p.z()), 0.f});
    }
  return pts;
}
}  // namespace

TEST(FreeSpace, BeamsGrazingAFlatSurfaceDoNotSeeItEmpty) {
  // DESIGN §2e, grazing beams: a roof 0.19 m under the sensor, between the rings' returns on it
  // (x 9.07 and 10.88), holds surface in the lower part of its voxel (z -0.2..0), through which
  // the rings just above pass on to the wall: they would see the roof's points empty. They run
  // within `margin` of the roof's plane there, and mark nothing; the space a ring well above
  // crosses (z 0..0.2) is still seen empty, as is the space before the box. Without graze_reach
  // the rings passing over the roof mark it; without flat_slope every ring does.
  const Eigen::Vector3f roof(10.5f, 0.f, -0.19f), above(10.5f, 0.f, 0.1f), before(5.f, 0.f, -0.1f);
  MapParams p = params();
  p.hit_inflate = 0;  // the roof's voxel at x 10.5 holds no return of its own
  const auto count = [&](const MapParams& q, const Eigen::Vector3f& at_point) {
    FreeSpaceMap fs(q);
    fs.insertScan(roofScene(), at(0), 0);
    return fs.evidence(at_point).count;
  };
  EXPECT_EQ(count(p, roof), 0);
  EXPECT_EQ(count(p, above), 1);
  EXPECT_EQ(count(p, before), 1);
  MapParams no_reach = p;
  no_reach.graze_reach = 0;
  EXPECT_EQ(count(no_reach, roof), 1);
  MapParams off = p;
  off.flat_slope = 0;
  EXPECT_EQ(count(off, roof), 1);
  EXPECT_EQ(count(off, above), 1);
}

namespace {
// A VLP-16 (rings every 2 degrees, -15 to 15; columns every 0.2 degree over -110 to -70) 1.73 m
// over the road, beside a parked car (x -2.2..2.2, y -3.2..-1.4, its roof `roof` m under the
// sensor) before a facade at y = -10: each beam's first hit, sensor frame, kept where the lidar
// returns it (2 m to 120 m): the rings that meet the car nearer than 2 m return nothing.
std::vector<PointXYZI> carPassedCloseBySparseLidar(double roof) {
  std::vector<PointXYZI> pts;
  const Eigen::Vector3d lo(-2.2, -3.2, -1.73), hi(2.2, -1.4, -roof);
  for (int e = -15; e <= 15; e += 2)
    for (int c = -550; c <= -350; ++c) {
      const double el = e * M_PI / 180, az = c * 0.2 * M_PI / 180;
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                              std::sin(el));
      double t = 10 / -d.y();                         // the facade
      if (d.z() < 0) t = std::min(t, -1.73 / d.z());  // the road
      double t0 = 0, t1 = t;                          // the car: slabs
      for (int i = 0; i < 3; ++i) {
        if (d[i] == 0) continue;
        const double a = lo[i] / d[i], b = hi[i] / d[i];
        t0 = std::max(t0, std::min(a, b));
        t1 = std::min(t1, std::max(a, b));
      }
      if (t0 <= t1) t = t0;
      if (t < 2 || t > 120) continue;
      const Eigen::Vector3d q = t * d;
      pts.push_back({float(q.x()), float(q.y()), float(q.z()), 0.f});
    }
  return pts;
}
}  // namespace

TEST(FreeSpace, ASparseLidarDoesNotSeeEmptyARoofItPassesClose) {
  // DESIGN §2e, grazing beams: a car's roof 0.23 m under the sensor, passed at 1.4 m, returns
  // only the ring at -5 degrees (2.63 m out); the rings below it meet the car within the lidar's
  // 2 m and return nothing, so that return has no lower neighbour to tell its surface. The ring
  // runs 0.07-0.17 m over the roof from its edge to 2.1 m, in the roof's voxels (z 1.4-1.6): seen
  // empty, the roof's points there went (a VLP-16 on the simulated street lost 5.7 % of the
  // static map, whole cars with them). A descending beam with nothing below it is taken to end on
  // a level surface. A roof 0.28 m under it also returns the ring at -7 degrees (2.28 m out),
  // with nothing below that one: the ring at -5 degrees, flat from it, goes back to where its
  // stretch starts. Without the grazing beams the roofs are seen empty; the space well above
  // them is either way.
  const Eigen::Isometry3d pose(Eigen::Translation3d(0, 0, 1.73));
  const auto counts = [&](const MapParams& q, double roof, float z) {
    FreeSpaceMap fs(q);
    fs.insertScan(carPassedCloseBySparseLidar(roof), pose, 0);
    int seen = 0;
    for (float x = -0.9f; x <= 0.9f; x += 0.2f)
      for (float y : {-1.5f, -1.7f, -1.9f}) seen += fs.evidence({x, y, z}).count;
    return seen;
  };
  MapParams off = params();
  off.flat_slope = 0;
  for (const double roof : {0.23, 0.28}) {
    const float top = static_cast<float>(1.73 - roof);
    EXPECT_GT(counts(off, roof, top), 10) << roof;  // the rings above see the roof's voxels empty
    EXPECT_EQ(counts(params(), roof, top), 0) << roof;
    EXPECT_GT(counts(params(), roof, 1.9f), 20) << roof;  // 0.4 m over it: still seen empty
  }
}

namespace {
// Rings every 0.5 degree over -1.5..1.5 and columns `step_deg` apart over -90..0 degrees of
// azimuth, beside a side (a wall, a parked car's) along x at y = -1.5 from x = 2 to 40, before a
// facade at x = 60: each beam's first hit.
std::vector<PointXYZI> sidePassedClose(double step_deg) {
  std::vector<PointXYZI> pts;
  for (int e = -3; e <= 3; ++e)
    for (double a = -90 + step_deg / 2; a < 0; a += step_deg) {
      const double el = e * 0.5 * M_PI / 180, az = a * M_PI / 180;
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                              std::sin(el));
      double t = 60 / d.x();
      if (const double ts = -1.5 / d.y(); d.x() * ts >= 2 && d.x() * ts <= 40) t = ts;
      const Eigen::Vector3d q = t * d;
      pts.push_back({float(q.x()), float(q.y()), float(q.z()), 0.f});
    }
  return pts;
}
}  // namespace

TEST(FreeSpace, BeamsEndingOnASideAtAGrazingAngleDoNotSeeItEmpty) {
  // DESIGN §2e, grazing sides: a side 1.5 m beside the sensor is met at sin(alpha) = 1.5 / x. An
  // Ouster at 512 columns (0.70 degrees) returns from it every x^2 0.0123 / 1.5 m along it, over
  // 2 hit_inflate apart beyond 9 m; each beam runs within margin of the side for 0.32 x / 1.5 m
  // before its end, through the side's voxels between the returns' protected neighbourhoods: the
  // side's surface 10-35 m ahead was seen empty. With grazing sides it is not; the space 0.6 m
  // off it still is. Columns of 0.17 degrees (an HDL-64E's) return every 0.2 m at 10 m and
  // protect the side by their neighbourhoods alone out to 18 m, not beyond. A moving return's
  // beam marks its stretch (what a mover leaves, as hit_inflate).
  const auto seen = [&](const MapParams& q, double step_deg, float y, bool moving = false) {
    const auto pts = sidePassedClose(step_deg);
    std::vector<uint8_t> flags(pts.size(), moving ? 1 : 0);
    FreeSpaceMap fs(q);
    fs.insertScan(pts, at(0), 0, &flags);
    int n = 0;
    for (float x = 10.f; x <= 35.f; x += 0.1f)
      for (const float z : {-0.1f, 0.1f}) n += fs.evidence({x, y, z}).count;
    return n;
  };
  MapParams off = params();
  off.grazing_sides = false;
  const double ouster = 360.0 / 512, hdl64 = 360.0 / 2083;
  EXPECT_GT(seen(off, ouster, -1.5f), 60);  // measured 124 of 502
  EXPECT_EQ(seen(params(), ouster, -1.5f), 0);
  EXPECT_GT(seen(off, hdl64, -1.5f), 20);  // measured 40, all beyond 18 m
  EXPECT_EQ(seen(params(), ouster, -0.9f), seen(off, ouster, -0.9f));  // 0.6 m off it
  EXPECT_GT(seen(params(), ouster, -0.9f), 250);
  EXPECT_EQ(seen(params(), hdl64, -1.5f), 0);
  EXPECT_GT(seen(params(), ouster, -1.5f, true), 60);  // measured 138
  // The stretches (GrazingStretches::side): only on the side, only where its returns lie more
  // than 2 hit_inflate apart (9 m out at 0.70 degrees, 18 m at 0.17; the facade too, met at a
  // grazing angle far to the side).
  const MapParams m;
  for (const double step : {ouster, hdl64}) {
    const auto pts = sidePassedClose(step);
    std::vector<float> azimuth(pts.size());
    for (std::size_t n = 0; n < pts.size(); ++n) azimuth[n] = std::atan2(pts[n].y, pts[n].x);
    const double bin = freeSpaceAzimuthBin(pts, m.beam_spacing);  // as the map bins it
    GrazingStretches g;
    g.compute(pts, Eigen::Matrix3f::Identity(), azimuth, m.flat_slope, m.margin, m.graze_reach, bin,
              m.hit_inflate);
    ASSERT_EQ(g.side().size(), pts.size());
    const double gate = std::sqrt(2 * m.hit_inflate * 1.5 / bin);  // x^2 bin / 1.5 = 2 hit_inflate
    std::size_t on = 0, wrong = 0;                                 // of the side's returns
    for (std::size_t n = 0; n < pts.size(); ++n) {
      const bool side = std::abs(pts[n].y + 1.5f) < 1e-3f;
      const bool stretch = std::isfinite(g.side()[n]);
      if (side && pts[n].x > gate + 1 && pts[n].x < 38) {
        on += stretch;
        wrong += !stretch;
      } else if (side && stretch && pts[n].x < gate - 1) {
        ++wrong;
      }
    }
    EXPECT_GT(on, 50u) << step;  // measured 70 / 98
    EXPECT_EQ(wrong, 0u) << step;
  }
}

TEST(FreeSpace, ScanIndicesUpToTheLargestItCountsAndAClearErrorBeyond) {
  // The voxels keep scan indices in 24 bits: the largest is kept exactly (a drive of 19 days at
  // 10 Hz), the next and a negative one are refused with the index in the message.
  const int64_t top = FreeSpaceMap::kMaxScan;
  FreeSpaceMap fs(params());
  fs.insertScan(ring(20.f), at(0), top - 1);
  fs.insertScan(ring(20.f, {{10.05f, 0.f, 0.f, 0.f}}), at(0), top);
  const FreeEvidence e = fs.evidence({10.05f, 0.f, 0.f});
  EXPECT_EQ(e.first, top - 1);
  EXPECT_EQ(e.last, top - 1);
  EXPECT_EQ(e.last_hit, top);
  EXPECT_EQ(e.count, 1);
  EXPECT_EQ(e.hits, 1);
  for (const int64_t bad : {top + 1, int64_t(-1)}) {
    try {
      fs.insertScan(ring(20.f), at(0), bad);
      ADD_FAILURE() << "scan " << bad << " accepted";
    } catch (const std::out_of_range& err) {
      EXPECT_NE(std::string(err.what()).find(std::to_string(bad)), std::string::npos) << err.what();
    }
  }
  EXPECT_EQ(fs.evidence({10.05f, 0.f, 0.f}), e);  // a refused scan changes nothing
}

TEST(FreeSpace, TheVoxelsLiveInPagesOfTheirOwnNotInMallocsHeap) {
  // The map's memory lives the whole run: carved from the holes a scan's freed buffers leave in
  // malloc's arenas, it pinned them and the arenas grew with the drive (doc/BENCHMARK.md, "The
  // free space in pages of its own"). Its blocks and voxels are in pages from the kernel; the
  // heap holds only its key table and per-scan scratch.
#if !defined(__GLIBC__) || defined(CLEANMAP_SANITIZED)
  GTEST_SKIP() << "needs glibc's own malloc (mallinfo2)";
#else
  FreeSpaceMap fs(params());
  fs.insertScan(ring(20.f), at(0), 0);  // the per-scan scratch sized once
  const std::size_t heap0 = mallinfo2().uordblks, map0 = fs.bytes();
  for (int k = 1; k <= 40; ++k) fs.insertScan(ring(20.f), at(1.5 * k), k);  // 60 m of new street
  const std::size_t heap1 = mallinfo2().uordblks, map = fs.bytes() - map0;
  const std::size_t heap = heap1 > heap0 ? heap1 - heap0 : 0;
  EXPECT_GT(map, std::size_t(1) << 20);  // the map grew
  EXPECT_LT(heap, map / 8) << "heap +" << heap << " B, map +" << map << " B";
  // Copies go on as the original does, each in pages of its own: one left alone is unchanged.
  std::vector<FreeEvidence> before;
  for (float x = -15; x <= 75; x += 0.2f) before.push_back(fs.evidence({x, 0.5f, 0.05f}));
  FreeSpaceMap copy(fs), idle(fs);
  copy.insertScan(ring(18.f), at(0), 41);
  fs.insertScan(ring(18.f), at(0), 41);
  std::size_t i = 0, checked = 0;
  for (float x = -15; x <= 75; x += 0.2f, ++i) {
    const Eigen::Vector3f q(x, 0.5f, 0.05f);
    ASSERT_EQ(idle.evidence(q), before[i]);
    ASSERT_EQ(copy.evidence(q), fs.evidence(q));
    checked += copy.evidence(q).count > before[i].count;
  }
  EXPECT_GT(checked, 100u);
#endif
}

TEST(FreeSpace, AnArrivalOverASurfaceThatStoodIsItsTopSeenThroughFromAfar) {
  // DESIGN §2e, "Decision": a voxel seen empty by arrived_scans scans before its first return
  // goes (something came and stood), unless the voxel right under it was returned from without
  // such a lead: a surface stood there from its first return on, and the voxel over it is its
  // top, seen through at a grazing angle before the rings came close enough to meet it
  // (kitti_residential: a low bush's top, 35 m ahead in scans 0-11).
  MapParams p = params();
  p.policy = MapPolicy::kTransient;
  p.free_ratio = 10;    // neither this ratio ...
  p.vacated_scans = 0;  // ... nor a run after the last return decides: the arrival alone
  p.between_scans = 0;
  p.flat_slope = 0;  // no grazing stretches: the beams below mark what they cross
  const Eigen::Isometry3d pose(Eigen::Translation3d(0, 0, 0.3));  // the sensor 0.3 m up
  // World z 0.3 is voxel layer 1 (the top, V), z 0.1 layer 0 (under it, B); x 10.1: cell 50.
  const PointXYZI top{10.1f, 0.f, 0.f, 0.f}, under{10.1f, 0.f, -0.2f, 0.f};
  // A cone of beams 0.4 m down at 20 m: the one at azimuth 0 crosses B at x = 10 (a lone beam
  // would start far out: the walk's levels take every azimuth bin to hold one, DESIGN §2e).
  const auto past_under = [] {
    std::vector<PointXYZI> c;
    for (const auto& q : ring(20.f)) c.push_back({q.x, q.y, -0.4f, 0.f});
    return c;
  }();
  const auto with = [](std::vector<PointXYZI> a, const std::vector<PointXYZI>& more) {
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  const Eigen::Vector3f v(10.1f, 0.f, 0.3f), b(10.1f, 0.f, 0.1f);
  FreeSpaceMap surface(p), box(p);
  for (int k = 0; k < 11; ++k) {
    // The surface: B returned from in scan 0, V seen empty in scans 1-6, returned from after.
    surface.insertScan(k == 0   ? ring(20.f, {under})
                       : k <= 6 ? ring(20.f)
                                : ring(20.f, {top}),
                       pose, k);
    // A box that comes in scan 7: V and B both seen empty in scans 0-6, returned from after.
    box.insertScan(k <= 6 ? with(ring(20.f), past_under) : ring(20.f, {top, under}), pose, k);
  }
  const FreeEvidence sv = surface.evidence(v), sb = surface.evidence(b);
  EXPECT_EQ(sv.lead, 6);
  EXPECT_EQ(sv.hits, 4);
  EXPECT_EQ(sb.hits, 1);
  EXPECT_EQ(sb.lead, 0);
  const FreeEvidence bv = box.evidence(v), bb = box.evidence(b);
  EXPECT_EQ(bv.lead, 7);
  EXPECT_EQ(bb.lead, 7);
  // One voxel alone reads both as arrivals; with the voxel under it, only the box came.
  EXPECT_TRUE(removedByPolicy(sv, 8, p));
  EXPECT_EQ(policyVerdict(sv, 8, p), PolicyVerdict::kIfArrived);
  EXPECT_FALSE(surface.removed(v, 8, p));
  EXPECT_TRUE(box.removed(v, 8, p));
  FreeSpaceMap::Lookup in_a_row(box);
  EXPECT_TRUE(in_a_row.removed(v, 8, p));
  // B itself stands on nothing the map has seen: its own arrival stands.
  EXPECT_TRUE(box.removed(b, 8, p));
  // Without the arrival rule the ratio keeps both.
  p.arrived_scans = 0;
  EXPECT_FALSE(box.removed(v, 8, p));
  EXPECT_EQ(policyVerdict(bv, 8, p), PolicyVerdict::kKept);
}
