// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-icp-slam: MRPT's ICP-SLAM application (mrpt::apps::ICP_SLAM_App_Rawlog, as the icp-slam
// program) with cleanmap's map plugins loaded, so a [MappingApplication] map list may hold
// cleanmap_moving and cleanmap_ground layers (DESIGN §4b, doc/MRPT.md step d). MRPT's icp-slam
// cannot load plugins.
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>

#include <mrpt/apps/ICP_SLAM_App.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CSensoryFrame.h>

#include "../common/cli.h"
#include "../common/memory.h"
#include "../common/process_times.h"
#include "cleanmap/maps/map_config.h"
#include "cleanmap/maps/moving_objects_map.h"

namespace {

constexpr const char* kUsage = R"(usage: cleanmap-icp-slam CONFIG.ini [DATASET.rawlog]

Runs MRPT's ICP-SLAM (2D: x, y, heading; the icp-slam program of MRPT) with cleanmap's map
plugins: the [MappingApplication] section may declare cleanmap_moving_count = 1 and
cleanmap_ground_count = 1 beside MRPT's own maps (ICP aligns against the first points map). The
ini's cleanmap sections are checked as cleanmap checks them (unknown maps and keys are errors).
Outputs, in the ini's logOutput_dir, are icp-slam's: _finalmap_.simplemap, the estimated path,
and _finalmaps_.txt_NN_<map> for every map; for the cleanmap_moving layer
_static.ply / _moving.ply / _trajectory.txt (its last K scans decided). See doc/MRPT.md and
config/icp_slam_kitti.ini. The cleanmap_moving layer's free space (static_map.clean) grows with
the ground covered (0.4-0.8 GiB per km of street); one warning line when it passes half the
memory (CLEANMAP_MEMORY_MIB=N sets it).
)";

// MRPT 2.5.8's points maps drop the robot pose when inserting a CObservationPointCloud
// (MRPT_NOTES), so ICP-SLAM would pile every scan at the origin. The same points as a
// CObservation3DRangeScan (points only, sensor frame) are inserted where the robot is.
::mrpt::obs::CObservation::Ptr asRangeScan(const ::mrpt::obs::CObservation::Ptr& obs) {
  const auto pc = std::dynamic_pointer_cast<::mrpt::obs::CObservationPointCloud>(obs);
  if (!pc) return obs;
  pc->load();
  auto r = ::mrpt::obs::CObservation3DRangeScan::Create();
  r->timestamp = pc->timestamp;
  r->sensorLabel = pc->sensorLabel;
  r->sensorPose = pc->sensorPose;
  r->maxRange = 200.0f;
  r->hasPoints3D = true;
  if (pc->pointcloud) {
    const auto& x = pc->pointcloud->getPointsBufferRef_x();
    const auto& y = pc->pointcloud->getPointsBufferRef_y();
    const auto& z = pc->pointcloud->getPointsBufferRef_z();
    r->points3D_x.assign(x.begin(), x.end());
    r->points3D_y.assign(y.begin(), y.end());
    r->points3D_z.assign(z.begin(), z.end());
    r->points3D_idxs_x.assign(x.size(), 0);  // no image: MRPT's serialization wants the sizes
    r->points3D_idxs_y.assign(x.size(), 0);
  }
  return r;
}

class App : public ::mrpt::apps::ICP_SLAM_App_Rawlog {
 protected:
  bool impl_get_next_observations(::mrpt::obs::CActionCollection::Ptr& action,
                                  ::mrpt::obs::CSensoryFrame::Ptr& observations,
                                  ::mrpt::obs::CObservation::Ptr& observation) override {
    // DESIGN §2e: our layers' free space, as the entries read so far left it (MRPT's loop
    // inserts each entry into the maps after this returns).
    memory_warning_.check(cleanmap_maps::CMovingObjectsMap::freeSpaceBytesOfAll(), entries_);
    if (!ICP_SLAM_App_Rawlog::impl_get_next_observations(action, observations, observation))
      return false;
    if (observation || observations) ++entries_;
    if (observation) observation = asRangeScan(observation);
    if (observations)
      for (auto& o : *observations) o = asRangeScan(o);
    return true;
  }

 public:
  std::size_t entries() const { return entries_; }

 private:
  cleanmap::cli::FreeSpaceWarning memory_warning_{"cleanmap-icp-slam", "(rawlog-edit --cut)"};
  std::size_t entries_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    std::cout << kUsage;
    return argc < 2 ? 2 : 0;
  }
  cleanmap::cli::useHugePages(argv);
  cleanmap::cli::keepFreedMemory();
  try {
    cleanmap_maps::registerMaps();
    // Our checks first, for one clear line (MRPT would ignore a misspelled map silently).
    cleanmap_maps::loadMapConfig(argv[1], "MappingApplication");
    App app;
    app.quits_with_esc_key = false;
    app.initialize(argc, argv);
    app.run();
    // The whole command (the ini's logOutput_dir is required by MRPT's run()).
    std::printf("cleanmap-icp-slam: %zu rawlog entries%s; results in %s\n", app.entries(),
                cleanmap::cli::processTimesText().c_str(),
                app.params.read_string("MappingApplication", "logOutput_dir", "log_out").c_str());
  } catch (const std::exception& e) {
    std::cerr << "cleanmap-icp-slam: error: " << cleanmap::cli::errorLine(e) << "\n";
    return 1;
  }
  return 0;
}
