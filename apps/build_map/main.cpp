// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-build-map: builds the maps of an MRPT ini (ours and MRPT's own) from a posed rawlog,
// KITTI folder or .simplemap, as MRPT's observations2map would if it loaded plugins
// (DESIGN §4b, doc/MRPT.md).

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <set>
#include <string>

#include <mrpt/io/CFileOutputStream.h>
#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/opengl/COpenGLScene.h>
#include <mrpt/opengl/CSetOfObjects.h>
#include <mrpt/poses/CPose3DPDF.h>
#include <mrpt/serialization/CArchive.h>

#include "../common/cli.h"
#include "../common/memory.h"
#include "../common/process_times.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/free_space.h"
#include "cleanmap/io/files.h"
#include "cleanmap/maps/map_config.h"
#include "cleanmap/maps/moving_objects_map.h"
#include "cleanmap/mrpt/convert.h"
#include "cleanmap/mrpt/input.h"
#include "cleanmap/mrpt/rawlog.h"

namespace fs = std::filesystem;

namespace {

constexpr const char* kUsage = R"(usage: cleanmap-build-map INPUT -c CONFIG.ini -o OUTDIR [options]

Builds every map that CONFIG.ini declares (MRPT's own maps and cleanmap's cleanmap_moving /
cleanmap_ground layers) from posed scans, as MRPT's observations2map would if it could load
plugins. Each scan is inserted at its pose; cleanmap_moving maps are flushed at the end.

INPUT               a posed MRPT rawlog (CObservationRobotPose + lidar observations, e.g. from
                    cleanmap-kitti2rawlog or cleanmap's cleaned.rawlog), a KITTI folder with
                    poses, or a .simplemap (pose + sensory frame pairs)
-c, --config FILE   MRPT ini with the map list (checked: unknown maps, sections, keys are errors)
-o, --output DIR    written as a whole (an error leaves it as it was); an earlier build there is
                    replaced, another non-empty folder refused without --force. Never the
                    input, a folder holding it, or a non-empty folder inside it
--map-section NAME  the section listing the maps (default: MappingApplication, map, MetricMap)
--force             replace DIR even if it is a non-empty folder that holds no build
Writes into DIR:
  maps.bin          the CMultiMetricMap, serialized (mrpt::serialization::archiveFrom(file) >> map;
                    load libcleanmap_maps.so first)
  maps.3Dscene      every map's 3D view, for SceneViewer3D
  map_*             each map's own files (saveMetricMapRepresentationToFile)
A cleanmap_moving layer's free space (static_map.clean) grows with the ground covered (0.4-0.8 GiB
per km of street); one warning line when it passes half the memory (CLEANMAP_MEMORY_MIB=N sets it).
Exit status: 0 done, 1 error (one line), 2 bad command line.
)";

// MRPT 2.5.8's points maps drop the robot pose of a CObservationPointCloud (MRPT_NOTES): give the
// whole pose as the sensor pose and insert at the origin, which every map composes the same way.
void insertAt(::mrpt::maps::CMultiMetricMap& maps, ::mrpt::obs::CObservation& obs,
              const ::mrpt::poses::CPose3D& robot) {
  if (auto* pc = dynamic_cast<::mrpt::obs::CObservationPointCloud*>(&obs)) {
    pc->load();
    ::mrpt::poses::CPose3D sensor;
    pc->getSensorPose(sensor);
    pc->setSensorPose(robot + sensor);
    maps.insertObservation(obs, ::mrpt::poses::CPose3D());
  } else {
    maps.insertObservation(obs, robot);
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string input, outdir, config, section;
  bool force = false;
  cleanmap::cli::useHugePages(argv);
  cleanmap::cli::keepFreedMemory();
  cleanmap::cli::Args args("cleanmap-build-map", argc, argv);
  while (!args.done()) {
    const std::string a = args.next();
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "-o" || a == "--output")
      outdir = args.value(a);
    else if (a == "-c" || a == "--config")
      config = args.value(a);
    else if (a == "--map-section")
      section = args.value(a);
    else if (a == "--force")
      force = true;
    else if (!a.empty() && a[0] != '-' && input.empty())
      input = a;
    else
      args.unexpected(a);
  }
  if (input.empty() || outdir.empty() || config.empty())
    args.fail("need INPUT, -c CONFIG and -o OUTDIR");

  try {
    cleanmap_maps::registerMaps();
    cleanmap::mrpt::registerClasses();
    const auto mc = cleanmap_maps::parseMapConfig(cleanmap::io::readTextFile(config), config,
                                                  section, /*require_moving=*/false);
    // An earlier build (maps.bin and maps.3Dscene) is replaced; another folder only with
    // --force, and never one that would take the input with it.
    const auto isBuild = [](const std::string& d) {
      std::error_code ec;
      return fs::is_regular_file(fs::path(d) / "maps.bin", ec) &&
             fs::is_regular_file(fs::path(d) / "maps.3Dscene", ec);
    };
    cleanmap::io::requireOutsideInput(outdir, input, isBuild, "-o");
    cleanmap::io::requireReplaceableFolder(
        outdir, [&](const std::string& d) { return force || isBuild(d); },
        "cleanmap-build-map maps (no maps.bin)", "-o",
        ", or pass --force to replace it and everything in it");
    // A rawlog's external files are input too (those of the first scan, then of every scan).
    const auto requireOutsideExternals = [&](const cleanmap::FrameSource* src) {
      if (const auto* r = dynamic_cast<const cleanmap::mrpt::RawlogSource*>(src))
        for (const auto& dir : r->externalFolders())
          cleanmap::io::requireOutsideInput(outdir, dir, isBuild, "-o");
    };
    ::mrpt::maps::CMultiMetricMap maps;
    maps.setListOfMaps(mc.maps);
    // DESIGN §2e: the cleanmap_moving layers' free space grows with the ground covered.
    cleanmap::cli::FreeSpaceWarning memory_warning("cleanmap-build-map",
                                                   "(rawlog-edit --cut; a simplemap in parts)");
    const auto checkMemory = [&](std::size_t scans, bool all_decided) {
      std::size_t held = 0;
      for (const auto& m : maps.maps)
        if (auto mv = std::dynamic_pointer_cast<cleanmap_maps::CMovingObjectsMap>(m))
          held += all_decided && mv->freeSpace() ? mv->freeSpace()->bytes() : mv->freeSpaceBytes();
      memory_warning.check(held, scans);
    };

    std::size_t scans = 0;
    std::unique_ptr<cleanmap::FrameSource> src_read;  // a KITTI folder or a rawlog
    if (cleanmap::mrpt::isSimplemapName(input)) {
      cleanmap::mrpt::useExternalFilesFolderOf(input);  // relative external scans and images
      ::mrpt::maps::CSimpleMap sm;
      cleanmap::mrpt::loadSimplemap(input, sm);
      // Its external files, before any is read: each scan's must exist, and no folder of them
      // may be one that -o would replace.
      std::set<std::string> folders;
      for (std::size_t i = 0; i < sm.size(); ++i) {
        const auto& pair = sm.getAsPair(i);
        if (!pair.pose || !pair.sf)
          throw cleanmap::Error(input, "keyframe " + std::to_string(i) + " is empty");
        for (const auto& obs : *pair.sf)
          for (const auto& f :
               cleanmap::mrpt::externalFiles(*obs, input, "keyframe " + std::to_string(i))) {
            folders.insert(fs::absolute(f.path).parent_path().lexically_normal().string());
            std::error_code ec;
            if (f.what != "image" && !fs::is_regular_file(f.path, ec))
              throw cleanmap::mrpt::missingExternalFile(input, "keyframe " + std::to_string(i), f);
          }
      }
      for (const auto& dir : folders) cleanmap::io::requireOutsideInput(outdir, dir, isBuild, "-o");
      for (std::size_t i = 0; i < sm.size(); ++i) {
        auto& pair = sm.getAsPair(i);
        const ::mrpt::poses::CPose3D robot = pair.pose->getMeanVal();
        for (auto& obs : *pair.sf) insertAt(maps, *obs, robot);
        checkMemory(++scans, false);
      }
    } else {
      cleanmap::mrpt::InputOptions in;
      in.allow_empty_scans = true;
      in.load_images = false;
      src_read = cleanmap::mrpt::openInput(input, in);
      requireOutsideExternals(src_read.get());
      while (auto f = src_read->next()) {
        if (!f->scan.has_pose)
          throw cleanmap::Error(f->source,
                                "has no pose: cleanmap-build-map needs posed scans "
                                "(run cleanmap --poses gicp and use its cleaned.rawlog)");
        auto obs = ::mrpt::obs::CObservationPointCloud::Create();
        obs->pointcloud = cleanmap::mrpt::toPointsMap(f->scan.points);
        obs->timestamp = cleanmap::mrpt::toMrptTime(f->scan.timestamp);
        obs->sensorLabel = "LIDAR";
        insertAt(maps, *obs, cleanmap::mrpt::toCPose3D(f->scan.pose));
        checkMemory(++scans, false);
      }
    }
    if (scans == 0) throw cleanmap::Error(input, "holds no scans");
    requireOutsideExternals(src_read.get());
    if (const auto* r = dynamic_cast<const cleanmap::mrpt::RawlogSource*>(src_read.get()))
      if (const auto w = cleanmap::mrpt::timedBackWarning(*r); !w.empty())
        std::fprintf(stderr, "cleanmap-build-map: warning: %s\n", w.c_str());
    for (const auto& m : maps.maps)
      if (auto mv = std::dynamic_pointer_cast<cleanmap_maps::CMovingObjectsMap>(m)) mv->flush();
    checkMemory(scans, true);

    // Written beside DIR, then moved into place as a whole (io::StagedFolder).
    cleanmap::io::StagedFolder staged(outdir, "cleanmap-build-map");
    const fs::path staging(staged.path());
    {
      ::mrpt::io::CFileOutputStream f((staging / "maps.bin").string());
      ::mrpt::serialization::archiveFrom(f) << maps;
    }
    ::mrpt::opengl::COpenGLScene scene;
    auto objs = ::mrpt::opengl::CSetOfObjects::Create();
    maps.getVisualizationInto(*objs);
    scene.insert(objs);
    if (!scene.saveToFile((staging / "maps.3Dscene").string()))
      throw cleanmap::Error((staging / "maps.3Dscene").string(), "cannot be written");
    maps.saveMetricMapRepresentationToFile((staging / "map").string());
    staged.publish();
    // The whole command, as `time` sees it (its re-execution and MRPT's loading included).
    std::printf("cleanmap-build-map: %zu scans into %zu maps%s; results in %s\n", scans,
                maps.maps.size(), cleanmap::cli::processTimesText().c_str(), outdir.c_str());
  } catch (const std::exception& e) {
    std::cerr << "cleanmap-build-map: error: "
              << cleanmap::io::messageWithoutStaging(cleanmap::cli::errorLine(e), outdir,
                                                     "cleanmap-build-map")
              << '\n';
    return 1;
  }
  return 0;
}
