// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2.2, "Self returns" (findSelfReturns) on hand-made scans with a known answer.
#include <gtest/gtest.h>

#include "cleanmap/core/beam_index.h"
#include "cleanmap/core/self_returns.h"

using namespace cleanmap;

namespace {

// A scan in the sensor frame: the recording car's roof rack (a patch 1.6 m off the sensor), a
// truck's side 2.7 m to the right that keeps pace with the car (12 m long), and a wall 2.5 m to
// the left that does not (its returns are the same all along).
struct Scene {
  std::vector<PointXYZI> points;
  std::size_t rack_end = 0, truck_end = 0;
  Scene() {
    for (float x = -1.15f; x <= -0.85f; x += 0.03f)
      for (float y = 1.05f; y <= 1.35f; y += 0.03f) points.push_back({x, y, -0.6f, 0});
    rack_end = points.size();
    for (float x = -6; x <= 6; x += 0.1f)
      for (float z = -1.2f; z <= 1.0f; z += 0.1f) points.push_back({x, -2.7f, z, 0});
    truck_end = points.size();
    for (float x = -6; x <= 6; x += 0.1f)
      for (float z = -1.2f; z <= 1.0f; z += 0.1f) points.push_back({x, 2.5f, z, 0});
  }
};

std::vector<WindowScan> windowAt(const std::vector<const BeamIndex*>& beams,
                                 const std::vector<double>& xs) {
  std::vector<WindowScan> window;
  for (std::size_t k = 0; k < xs.size(); ++k) {
    WindowScan w;
    w.beams = beams[k];
    w.world_to_sensor = Eigen::Translation3d(-xs[k], 0, 0);  // the sensor at (x, 0, 0)
    window.push_back(w);
  }
  return window;
}

}  // namespace

TEST(SelfReturns, TheCarsOwnRackLeavesAMoverKeepingPaceStays) {
  const Scene s;
  const BeamIndex same(s.points, 0.01);
  const std::vector<uint8_t> member(s.points.size(), 1);
  std::vector<uint8_t> flagged(s.points.size(), 0);
  for (std::size_t i = 0; i < s.truck_end; ++i) flagged[i] = 1;  // the rack and the truck
  const auto window = windowAt({&same, &same, &same, &same}, {-3, -1.5, 1.5, 3});
  std::vector<uint8_t> self;
  const std::size_t n =
      findSelfReturns(s.points, member, flagged, Eigen::Vector3d::Zero(), window, 3.0, 0.3, self);
  EXPECT_EQ(n, s.rack_end);
  for (std::size_t i = 0; i < s.points.size(); ++i)
    ASSERT_EQ(self[i], i < s.rack_end) << i;  // the truck reaches beyond 3 m; the wall is static
  // The car standing (no window scan 1 m away) or crawling: nothing tells its own returns.
  EXPECT_EQ(findSelfReturns(s.points, member, flagged, Eigen::Vector3d::Zero(),
                            windowAt({&same, &same}, {-0.5, 0.5}), 3.0, 0.3, self),
            0u);
  // Off.
  EXPECT_EQ(
      findSelfReturns(s.points, member, flagged, Eigen::Vector3d::Zero(), window, 0, 0.3, self),
      0u);
  // A patch that is not in the same place in the other scans (a bag on a car that passes it at
  // 1.6 m) is no part of the car.
  Scene other;
  for (std::size_t i = 0; i < other.rack_end; ++i) other.points[i].x += 0.5f;
  const BeamIndex moved(other.points, 0.01);
  EXPECT_EQ(findSelfReturns(s.points, member, flagged, Eigen::Vector3d::Zero(),
                            windowAt({&moved, &moved, &same, &moved}, {-3, -1.5, 1.5, 3}), 3.0, 0.3,
                            self),
            0u);
  // Three of four scans see it in place: it is the car's (a return missed now and then).
  EXPECT_EQ(
      findSelfReturns(s.points, member, flagged, Eigen::Vector3d::Zero(),
                      windowAt({&moved, &same, &same, &same}, {-3, -1.5, 1.5, 3}), 3.0, 0.3, self),
      s.rack_end);
}
