// SPDX-License-Identifier: BSD-3-Clause
#include <gtest/gtest.h>

#include <fstream>

#include "cleanmap/io/kitti.h"
#include "cleanmap/io/objects.h"
#include "test_data.h"

using namespace cleanmap;

TEST(Objects, ReadsHighwayTracks) {
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  ASSERT_TRUE(seq.objectsPath().has_value());
  const auto objects = io::readObjects(*seq.objectsPath());
  ASSERT_EQ(objects.size(), 14u);  // LABELS.md lists 14 tracked objects
  EXPECT_EQ(objects[0].cls, "truck");
  EXPECT_TRUE(objects[0].movingAnywhere());
  std::size_t moving_objects = 0;
  for (const auto& o : objects) moving_objects += o.movingAnywhere();
  EXPECT_EQ(moving_objects, 7u);  // A1-A5, O2, O3 move; the left-lane queue stands
}

TEST(Objects, MovingBoxesHoldTheMovingLabels) {
  // Labels were made from the boxes (inflated 0.15 m): every labelled-moving point of a scan lies
  // in the box of an object that moves in that scan.
  CLEANMAP_REQUIRE_DATASET("kitti_highway");
  const auto seq = io::KittiSequence::open(test::dataDir() + "/kitti_highway");
  const auto objects = io::readObjects(*seq.objectsPath());
  for (std::size_t f : {0u, 15u, 29u}) {
    const Scan s = seq.loadScan(f);
    const Labels l = seq.loadLabels(f, s.original_size);
    std::size_t moving = 0, inside = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (gtClass(l[s.originalIndex(i)]) != GtClass::kMoving) continue;
      ++moving;
      const Eigen::Vector3d p = s.points[i].xyz().cast<double>();
      for (const auto& o : objects) {
        const auto it = o.frames.find(f);
        if (it != o.frames.end() && it->second.motion == io::Motion::kMoving &&
            it->second.contains(p, 0.2)) {
          ++inside;
          break;
        }
      }
    }
    ASSERT_GT(moving, 1000u);
    EXPECT_GT(static_cast<double>(inside) / moving, 0.99) << "frame " << f;
  }
}

TEST(Objects, BadJsonIsAnError) {
  const auto dir = test::scratchDir("objects_bad");
  std::ofstream(dir / "objects.json") << "[{\"id\": 1, \"frames\": {\"0\": {\"center\": [1, 2]}}}]";
  test::expectError([&] { io::readObjects((dir / "objects.json").string()); }, "objects.json",
                    "center is not an array of 3 numbers");
  std::ofstream(dir / "broken.json") << "[{\"id\": ";
  test::expectError([&] { io::readObjects((dir / "broken.json").string()); }, "broken.json",
                    "invalid JSON");
}
