// SPDX-License-Identifier: BSD-3-Clause
// Writes a one-scan rawlog with the installed library and reads it back, and creates our map
// plugin from ini text through MRPT's CMultiMetricMap: exit 0 iff both work.
#include <cstdio>
#include <cstring>

#include <mrpt/maps/CMultiMetricMap.h>

#include <cleanmap/core/types.h>
#include <cleanmap/maps/map_config.h>
#include <cleanmap/maps/moving_objects_map.h>
#include <cleanmap/mrpt/rawlog.h>

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : "consumer.rawlog";
  cleanmap::Frame f;
  f.scan.points = {{1.f, 2.f, 3.f, 0.5f}, {-4.f, 5.5f, -1.7f, 0.25f}};
  f.scan.timestamp = 12.5;
  f.scan.has_pose = true;
  f.scan.pose.translation() = Eigen::Vector3d(1, 2, 3);
  cleanmap::mrpt::RawlogWriter w(path);
  w.write(f, std::nullopt);
  w.close();
  cleanmap::mrpt::RawlogSource src(path);
  const auto g = src.next();
  const bool same = g && g->scan.size() == 2 &&
                    std::memcmp(g->scan.points.data(), f.scan.points.data(), 32) == 0 &&
                    g->scan.pose.isApprox(f.scan.pose);
  std::printf("consumer: round trip %s\n", same ? "ok" : "FAILED");
  const auto mc = cleanmap_maps::parseMapConfig(
      "[map]\ncleanmap_moving_count = 1\n[map_cleanmap_moving_00_creationOpts]\nds.window_k = 4\n",
      "consumer.ini");
  mrpt::maps::CMultiMetricMap maps;
  maps.setListOfMaps(mc.maps);
  const auto m = maps.mapByClass<cleanmap_maps::CMovingObjectsMap>();
  const bool plugin = m && m->params().ds.window_k == 4;
  std::printf("consumer: map plugin %s\n", plugin ? "ok" : "FAILED");
  return same && plugin ? 0 : 1;
}
