// SPDX-License-Identifier: BSD-3-Clause
// cleanmap: moving-object removal over a KITTI folder or an MRPT rawlog (DESIGN §2, §4).
#include <unistd.h>
#include <chrono>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <iostream>
#include <optional>
#include <string>

#include <mrpt/maps/CMultiMetricMap.h>
#include "../common/cli.h"
#include "../common/memory.h"
#include "cleanmap/core/error.h"
#include "cleanmap/core/params.h"
#include "cleanmap/core/sanitized.h"

#include "cleanmap/core/stopwatch.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/io/output.h"
#include "cleanmap/io/prefetch.h"
#include "cleanmap/maps/ground_model_map.h"
#include "cleanmap/maps/map_config.h"
#include "cleanmap/maps/moving_objects_map.h"
#include "cleanmap/mrpt/input.h"
#include "cleanmap/mrpt/outputs.h"
#include "cleanmap/mrpt/rawlog.h"

namespace {

volatile std::sig_atomic_t g_signal = 0;
void onSignal(int sig) {
  g_signal = sig;
  std::signal(sig, SIG_DFL);  // a second Ctrl-C kills at once
}

struct Interrupted {
  int sig;
};
void checkSignal() {
  if (g_signal) throw Interrupted{static_cast<int>(g_signal)};
}

// Ends the process once its outputs are published: streams flushed, no destructors, no library
// finalizers. Under AddressSanitizer or ThreadSanitizer the process returns normally, so the leak
// check runs, the threads' joins are checked, and a race reported sets the exit status.
void exitNow(int code) {
#ifndef CLEANMAP_SANITIZED
  std::cout.flush();
  std::fflush(nullptr);
  std::_Exit(code);
#else
  (void)code;
#endif
}

constexpr const char* kUsage = R"(usage: cleanmap INPUT -o OUTDIR [options]

Finds the moving points in a sequence of lidar scans (Dempster-Shafer occupancy over a window of
K past and K future scans, after ground removal; doc/DESIGN.md §2) and writes, into OUTDIR:
  labels/<stem>.label   uint32 per original point: 251 moving, 9 static, 40 ground, 0 not classified
  static_map.ply/.pcd   compact static map (duplicates of the recent map left out), world frame,
                        RGB by height above the sensor
  static_map_full.ply   the clean map: every static point (ground included) within
                        static_map.radius (50 m) of its sensor, less what the sequence's free
                        space removed (static_map.policy; DESIGN §2e), world frame, RGB by height
  dynamic.ply/.pcd      the moving points (the windowed test), world frame, red
  map_removed.ply       the points the free-space cleaning removed from the map
  map_labels/<stem>.label  what the map did with each point: 251 removed, 9 kept, 40 ground,
                        0 beyond the map radius
  static_map.3Dscene    for SceneViewer3D: static map (one point per 0.1 m voxel), moving
                        points in red, trajectory (doc/MRPT.md)
  static_map.simplemap  every scan without its moving points, with its pose (MRPT CSimpleMap)
  cleaned.rawlog        per scan: CObservationRobotPose + CObservationPointCloud without the
                        moving points, for any MRPT SLAM or localization
  labelled.rawlog       per scan: pose + the scan coloured by label (RawLogViewer; doc/FORMATS.md)
  ground_model.ply/.txt the ground model map's cells (world grid of ground heights), when the
                        configuration declares a cleanmap_ground map (config/cleanmap.ini does)
  poses.txt             lidar poses used (KITTI 3x4 rows; poses_tum.txt: the same as TUM lines);
                        params.ini: the parameters of the run
  report.json, report.md  counts, time per stage, and precision/recall/IoU when INPUT has labels

INPUT                a KITTI odometry/SemanticKITTI or raw folder, an MRPT .rawlog, or a SLAM's
                     .simplemap (each keyframe's scans at its pose; --poses refine re-aligns
                     a 2D SLAM's poses in 6D)
-o, --output DIR     output folder. The run is written beside it and moved into place when
                     complete: an earlier cleanmap run there is replaced as a whole; an
                     interrupted or failed run leaves DIR as it was
--force              replace DIR even if it is a non-empty folder that holds no cleanmap run
-c, --config FILE    the maps and their parameters: an MRPT ini declaring a cleanmap_moving map
                     (and optionally a cleanmap_ground map), as config/cleanmap.ini, or a run's
                     flat params.ini. Unknown maps, sections and keys are errors. Default: the
                     values of config/cleanmap.ini
--map-section NAME   the section listing the maps (default: the first of MappingApplication,
                     map, MetricMap that declares maps)
--threads N          threads (default 2): the moving-point test's workers, and from 2 on the
                     registration, the free space and the map's read-ahead beside the pipeline
                     (the output files are always written beside it); results do not depend on it
--seed S             seed of the octree sampling (default 42; same seed, same output bit for bit)
--first N, --last M  process scans N..M only (indices in the input, inclusive)
--poses SOURCE       given: the input's poses (KITTI poses.txt / OXTS, rawlog CObservationRobotPose);
                     gicp: GICP scan-to-map odometry (DESIGN §2.1; a given first pose anchors it);
                     refine: GICP started from each given pose. Default: given when the first
                     scan has a pose, gicp otherwise. report.json says what each scan used.
--images MODE        on: check every moving candidate in the camera images of its window and
                     relabel static what looks the same in all of them (DESIGN §3; an error if
                     INPUT has no images and calibration); off: laser only; auto (default): on
                     where the input has images (KITTI image_2/, rawlog CObservationImage)
--lidar LABEL        rawlogs: read the scans of the lidar with this sensorLabel (default: the
                     first lidar's); those of other lidars are skipped, counted in report.json
                     (rawlog_sensors) and in one warning line
--camera LABEL       rawlogs: the same for the camera images
--save-overlays      write overlays/<stem>.png: each camera image with the scan's points, static
                     green, moving red, relabelled static by the camera yellow
--no-mrpt-outputs    skip the .3Dscene, .simplemap and the two rawlogs
--viewer-voxel M     voxel of the .3Dscene's decimation, metres (default 0.1; files keep every point)
--quiet              no progress line (there is none when stderr is not a terminal)
Scans without any valid point (0-byte .bin, all NaN) are kept as empty scans: labelled 0,
counted in report.json (empty_scans) and in one warning line.
Memory grows with the ground covered (the free space of static_map.clean: 0.4-0.8 GiB per km of
street); one warning line when it passes half the memory (CLEANMAP_MEMORY_MIB=N sets it).
Exit status: 0 done, 1 error (one line naming the file), 2 bad command line, 130 / 143
interrupted by SIGINT / SIGTERM (nothing written to DIR).
--help               this text
)";

}  // namespace

int main(int argc, char** argv) {
  std::string input, outdir, config, map_section, poses = "auto", images = "auto", lidar, camera;
  long threads = -1, first = 0, last = -1;
  long long seed = -1;
  bool quiet = false, progress_shown = false, force = false, mrpt_outputs = true, overlays = false;
  double viewer_voxel = 0.1;
  cleanmap::cli::useHugePages(argv);
  cleanmap::cli::keepFreedMemory();
  cleanmap::cli::Args args("cleanmap", argc, argv);
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
      map_section = args.value(a);
    else if (a == "--threads")
      threads = args.integer(a, 1);
    else if (a == "--seed")
      seed = args.integer(a);
    else if (a == "--first")
      first = args.integer(a);
    else if (a == "--last")
      last = args.integer(a);
    else if (a == "--poses")
      poses = args.value(a);
    else if (a == "--images")
      images = args.value(a);
    else if (a == "--lidar")
      lidar = args.value(a);
    else if (a == "--camera")
      camera = args.value(a);
    else if (a == "--save-overlays")
      overlays = true;
    else if (a == "--quiet")
      quiet = true;
    else if (a == "--force")
      force = true;
    else if (a == "--no-mrpt-outputs")
      mrpt_outputs = false;
    else if (a == "--viewer-voxel")
      viewer_voxel = args.number(a);
    else if (!a.empty() && a[0] != '-' && input.empty())
      input = a;
    else
      args.unexpected(a);
  }
  if (input.empty() || outdir.empty()) args.fail("need INPUT and -o OUTDIR");
  if (poses != "auto" && poses != "given" && poses != "gicp" && poses != "refine")
    args.fail("--poses is given, gicp or refine");
  if (last >= 0 && last < first) args.fail("--last must be >= --first");
  if (images != "auto" && images != "on" && images != "off")
    args.fail("--images is on, off or auto");
  if (overlays && images == "off") args.fail("--save-overlays needs the images (not --images off)");
  if (!(viewer_voxel > 0)) args.fail("--viewer-voxel must be > 0");

  quiet = quiet || !::isatty(STDERR_FILENO);  // progress lines only on a terminal, not in logs
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  try {
    cleanmap::cli::FreeSpaceWarning memory_warning("cleanmap", "with --first/--last");  // §2e
    // Never replace the input (its labels/ by ours), a folder holding it, or one inside it that
    // is no earlier run, --force or not.
    cleanmap::io::requireOutsideInput(outdir, input, cleanmap::io::isCleanmapRun, "-o");
    // The maps, through MRPT's factory from the ini (DESIGN §4b): the same sections work in a
    // user's CMultiMetricMap. A flat params.ini (a run's) declares the two maps implicitly.
    cleanmap_maps::registerMaps();
    std::string map_text = cleanmap_maps::mapConfigText(cleanmap::PipelineParams{});
    const std::string config_name = config.empty() ? "config/cleanmap.ini (defaults)" : config;
    if (!config.empty()) {
      map_text = cleanmap::io::readTextFile(config);
      if (!cleanmap_maps::isMapConfig(map_text)) {
        cleanmap::PipelineParams flat;
        cleanmap::io::parseParams(map_text, config, flat);
        map_text = cleanmap_maps::mapConfigText(flat);
      }
    }
    const auto map_config = cleanmap_maps::parseMapConfig(map_text, config_name, map_section);
    ::mrpt::maps::CMultiMetricMap maps;
    maps.setListOfMaps(map_config.maps);
    const auto moving = maps.mapByClass<cleanmap_maps::CMovingObjectsMap>();
    const auto ground = maps.mapByClass<cleanmap_maps::CGroundModelMap>();
    if (maps.mapByClass<cleanmap_maps::CMovingObjectsMap>(1) ||
        maps.mapByClass<cleanmap_maps::CGroundModelMap>(1))
      throw cleanmap::Error(config_name,
                            "declares more than one cleanmap_moving or "
                            "cleanmap_ground map; a cleanmap run fills one of each");
    for (const auto& m : maps.maps)
      if (!std::dynamic_pointer_cast<cleanmap_maps::CMovingObjectsMap>(m) &&
          !std::dynamic_pointer_cast<cleanmap_maps::CGroundModelMap>(m))
        std::fprintf(stderr,
                     "cleanmap: warning: %s: map %s is left empty (cleanmap fills only "
                     "its own maps; use it in cleanmap-icp-slam)\n",
                     config_name.c_str(), m->GetRuntimeClass()->className);
    cleanmap::PipelineParams params = moving->params();
    if (threads > 0) params.threads = static_cast<int>(threads);
    if (seed >= 0) params.seed = static_cast<uint64_t>(seed);
    params.poses = poses == "given"    ? cleanmap::PoseSource::kGiven
                   : poses == "gicp"   ? cleanmap::PoseSource::kGicp
                   : poses == "refine" ? cleanmap::PoseSource::kRefine
                                       : cleanmap::PoseSource::kAuto;
    if (images == "off") params.image.enabled = false;
    if (images == "on") params.image.enabled = true;
    moving->setParams(params);
    if (ground) {  // it is given the moving map's ground labels: the two must agree
      const auto g = ground->groundParams();
      const auto& m = params.ground;
      auto value = [](double v, bool autoable) {
        return autoable && v == 0 ? std::string("auto") : cleanmap::io::shortestDouble(v);
      };
      auto same = [&](const char* key, const std::string& moving_key, double a, double b,
                      bool autoable = false) {
        if (a != b)
          throw cleanmap::Error(
              config_name, std::string("the cleanmap_ground map's ") + key + " (" +
                               value(a, autoable) + ") differs from cleanmap_moving's " +
                               moving_key + " (" + value(b, autoable) +
                               "): cleanmap gives the ground map the moving map's ground labels");
      };
      same("cell", "ground.cell", g.cell, m.cell);
      same("step", "ground.step", g.step, m.step);
      same("height", "sensor.height", ground->insertionOptions.height, params.sensor.height, true);
      same("point_refine", "ground.point_refine", g.point_refine, m.point_refine);
      same("max_gap_cells", "ground.max_gap_cells", g.max_gap_cells, m.max_gap_cells);
    }

    cleanmap::mrpt::InputOptions in_opts;
    in_opts.allow_empty_scans = true;            // counted in the report
    in_opts.load_images = params.image.enabled;  // DESIGN §3
    in_opts.point_times = params.sensor.deskew != cleanmap::DeskewMode::kOff;  // DESIGN §2.0
    in_opts.lidar_label = lidar;
    in_opts.camera_label = camera;
    auto src = cleanmap::mrpt::openInput(input, in_opts);
    const auto* kitti = dynamic_cast<const cleanmap::io::KittiSequence*>(src.get());
    const auto* rawlog = dynamic_cast<const cleanmap::mrpt::RawlogSource*>(src.get());
    // A rawlog's external files (cleanmap-kitti2rawlog --external, rawlog-edit --externalize) are
    // input too: checked for the first scan's here, for every scan's before publishing.
    const auto requireOutsideExternals = [&] {
      if (rawlog)
        for (const auto& dir : rawlog->externalFolders())
          cleanmap::io::requireOutsideInput(outdir, dir, cleanmap::io::isCleanmapRun, "-o");
    };
    requireOutsideExternals();
    const bool evaluate = kitti && kitti->hasLabels();
    if (params.image.enabled && kitti) {  // a rawlog's camera is known from its first image
      if (images == "on" && (!src->camera() || !kitti->hasImages()))
        throw cleanmap::Error(input,
                              "--images on, but the input has no " +
                                  std::string(src->camera() ? "images" : "camera calibration") +
                                  " (KITTI: image_2/ and P2 in calib.txt; rawlog: "
                                  "CObservationImage)");
      moving->setCamera(src->camera());
    }
    moving->setSaveOverlays(overlays);
    moving->setRegisterAhead(true);  // with GICP and threads > 1 (issue #16)
    // The next frame is read and decoded while the pipeline decides this one (issue #16); the
    // KITTI reader's labels are still read here (its const loadLabels is safe beside that).
    auto prefetch = std::make_unique<cleanmap::io::PrefetchSource>(std::move(src));
    auto* prefetching = prefetch.get();
    src = std::move(prefetch);

    if (const auto n = src->sizeHint(); n && first >= static_cast<long>(*n))
      throw cleanmap::Error(input, "--first " + std::to_string(first) +
                                       " is beyond the end: the input has " + std::to_string(*n) +
                                       " scans (0.." + std::to_string(long(*n) - 1) + ")");
    cleanmap::io::OutputOptions out_opts;
    out_opts.force = force;
    cleanmap::io::OutputWriter out(outdir, input, params, out_opts);
    std::optional<cleanmap::mrpt::MrptOutputWriter> mrpt_out;
    if (mrpt_outputs) {
      cleanmap::mrpt::MrptOutputOptions mo;
      mo.viewer_voxel = viewer_voxel;
      mo.map_decisions = true;  // cleaned like static_map_full.ply (DESIGN §4a)
      mrpt_out.emplace(out.staging(), mo);
    }
    std::size_t seen = 0, empty = 0;
    const auto t0 = std::chrono::steady_clock::now();
    const auto total = src->sizeHint();
    double ground_ms = 0;
    moving->setStorePoints(false);  // streamed to the files below instead
    moving->setScanSink([&](cleanmap::ScanResult&& r) {
      checkSignal();
      if (ground) {
        const auto t = cleanmap::Clock::now();
        std::vector<uint8_t> flags(r.scan.size());
        for (std::size_t i = 0; i < flags.size(); ++i)
          flags[i] = r.labels[r.scan.originalIndex(i)] == cleanmap::kGround;
        ground->insertGround(r.scan, flags);
        ground_ms += cleanmap::msSince(t);
      }
      std::optional<cleanmap::MosCounts> eval;
      if (evaluate) {
        const auto truth = kitti->loadLabels(r.index, r.labels.size());
        eval = cleanmap::compareLabels(r.labels, truth, kitti->labelPath(r.index));
        std::size_t st = 0, mv = 0;  // were the camera's relabellings right? (DESIGN §3)
        for (const uint32_t i : r.relabelled_index) {
          const auto g = cleanmap::gtClass(truth[i]);
          st += g == cleanmap::GtClass::kStatic;
          mv += g == cleanmap::GtClass::kMoving;
        }
        if (params.image.enabled) out.addRelabelledTruth(st, mv);
      }
      out.write(r, eval);
      if (mrpt_out) mrpt_out->write(std::move(r));
      // DESIGN §2e: the free space's memory as the insertions finished so far left it (once more
      // below, when all are: a short run's may still be queued while its results come here).
      memory_warning.check(moving->freeSpaceBytes(), out.scans(), progress_shown);
      if (!quiet) {
        progress_shown = true;
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const double rate = static_cast<double>(out.scans()) / std::max(s, 1e-9);
        long todo = -1;
        if (total)
          todo =
              static_cast<long>(last >= 0 ? std::min<long>(last + 1, long(*total)) : long(*total)) -
              first;
        if (todo > 0)
          std::fprintf(stderr, "\rcleanmap: %zu/%ld scans, %.1f scans/s, ETA %.0f s   ",
                       out.scans(), todo, rate,
                       (static_cast<double>(todo) - double(out.scans())) / rate);
        else
          std::fprintf(stderr, "\rcleanmap: %zu scans, %.1f scans/s   ", out.scans(), rate);
      }
    });
    moving->setKeepScans(mrpt_outputs || ground);  // rawlogs and ground model use the points
    while (auto f = src->next()) {
      checkSignal();
      const long idx = static_cast<long>(f->index);
      ++seen;
      if (idx < first) continue;
      if (last >= 0 && idx > last) break;
      empty += f->scan.empty();
      if (params.image.enabled && !moving->camera() && f->image && src->camera())
        moving->setCamera(src->camera());  // a rawlog's, from its first image
      moving->insertFrame(std::move(*f));
    }
    out.inputEnded();  // the last scans are decided without new ones coming in
    const auto inner = prefetching->release();  // the reading thread has stopped
    if (rawlog)
      out.setSensors({rawlog->lidarLabel(), rawlog->cameraLabel(), rawlog->otherLidars(),
                      rawlog->otherCameras(), rawlog->scansTimedBack()});
    moving->flush();
    checkSignal();
    if (const auto* fs = moving->freeSpace())
      memory_warning.check(fs->bytes(), out.scans(), progress_shown);
    requireOutsideExternals();
    if (images == "on" && moving->totals().image_scans == 0)
      throw cleanmap::Error(input,
                            "--images on, but no scan came with a camera image and "
                            "calibration (rawlog: CObservationImage with its camera)");
    if (out.scans() == 0)
      throw cleanmap::Error(input, "no scans in the requested range: the input has " +
                                       std::to_string(seen) + " scans (--first " +
                                       std::to_string(first) + ")");
    // Paper §II-B: a scan is tested against the other scans of its window; alone, nothing is.
    if (out.scans() == 1)
      std::fprintf(stderr,
                   "cleanmap: warning: %s: one scan: the moving test compares each scan with the "
                   "others of its window, so every point is labelled static; give a sequence\n",
                   input.c_str());
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    // The ground model is whole once the last scan is handed on: it is saved on a thread of its
    // own beside the map's decision, which keeps about one core busy (issue #16).
    std::future<double> ground_saved;
    if (ground)
      ground_saved = std::async(params.threads > 1 ? std::launch::async : std::launch::deferred,
                                [&ground, dir = out.staging()] {
                                  const auto t = cleanmap::Clock::now();
                                  ground->saveMetricMapRepresentationToFile(dir + "/ground_model");
                                  return cleanmap::msSince(t);
                                });
    // The map's decisions first: the MRPT outputs hold what static_map_full.ply holds.
    out.writeMaps(moving->freeSpace(), [&](const cleanmap::io::MapScan& m) {
      if (mrpt_out) mrpt_out->writeMapScan(m.index, m.map_labels, m.kept, m.removed);
    });
    if (mrpt_out) {
      mrpt_out->finish();
      out.addOutputTime("mrpt", mrpt_out->writeMs());
    }
    if (ground_saved.valid()) out.addOutputTime("ground_model", ground_ms + ground_saved.get());
    out.finish(wall, moving->freeSpace());
    if (progress_shown) std::fprintf(stderr, "\n");
    // One lidar and one camera per run: the others' observations were skipped (counted).
    if (rawlog) {
      if (!rawlog->otherLidars().empty() && lidar.empty())
        std::fprintf(stderr,
                     "cleanmap: warning: %s: scans of lidar '%s' used; those of other lidars "
                     "skipped: %s; choose one with --lidar LABEL\n",
                     input.c_str(), rawlog->lidarLabel().c_str(),
                     cleanmap::mrpt::labelCounts(rawlog->otherLidars()).c_str());
      if (!rawlog->otherCameras().empty() && camera.empty() && params.image.enabled)
        std::fprintf(stderr,
                     "cleanmap: warning: %s: images of camera '%s' used; those of other cameras "
                     "skipped: %s; choose one with --camera LABEL\n",
                     input.c_str(), rawlog->cameraLabel().c_str(),
                     cleanmap::mrpt::labelCounts(rawlog->otherCameras()).c_str());
      if (const auto w = cleanmap::mrpt::timedBackWarning(*rawlog); !w.empty())
        std::fprintf(stderr, "cleanmap: warning: %s (report.json: rawlog_sensors)\n", w.c_str());
      // A 2D SLAM's keyframes: a 3D lidar's scans disagree where the ground and walls tilt
      // (ICP-SLAM's map of kitti_city: precision 0.435, 0.581 refined; doc/MRPT.md step d).
      if (rawlog->isSimplemap() && out.givenPosesArePlanar())
        std::fprintf(stderr,
                     "cleanmap: warning: %s: the keyframes' poses are planar (one height, no "
                     "roll or pitch), as a 2D SLAM's are; --poses refine re-aligns the scans in "
                     "6D from them\n",
                     input.c_str());
    }
    // DESIGN §2b: scans far apart, as a SLAM's keyframes may be (doc/MRPT.md step d).
    if (const auto gap = out.scanSpacing())
      if (const auto w = cleanmap::sparseScansWarning(gap->seconds, gap->metres); !w.empty())
        std::fprintf(stderr, "cleanmap: warning: %s: %s\n", input.c_str(), w.c_str());
    if (empty)
      std::fprintf(stderr,
                   "cleanmap: warning: %zu empty scans (no valid point) kept, labelled 0 "
                   "(report.json: empty_scans)\n",
                   empty);
    // DESIGN §2a: a configured mounting height the data contradicts (0.3 m: a curb, a bump).
    if (const auto h = out.measuredSensorHeight();
        h && params.sensor.height > 0 && std::abs(*h - params.sensor.height) > 0.3)
      std::fprintf(stderr,
                   "cleanmap: warning: %s: [sensor] height = %s m, but the ground measured in the "
                   "scans lies %.2f m below the sensor (report.json: sensor); set height = auto "
                   "or the right value\n",
                   config_name.c_str(), cleanmap::io::shortestDouble(params.sensor.height).c_str(),
                   *h);
    // DESIGN §2.1: estimated poses that are only the guess (a degenerate scene, too few
    // correspondences, a jump, a pull away from the odometry) are said, not left to report.json.
    if (const auto refused = out.refusedAlignments(); !refused.empty()) {
      std::size_t n = 0;
      std::string why;
      for (const auto& [reason, count] : refused) {
        n += count;
        why += (why.empty() ? "" : ", ") + reason + ": " + std::to_string(count);
      }
      std::fprintf(stderr,
                   "cleanmap: warning: GICP refused the alignment of %zu of %zu scans (%s); their "
                   "poses are the guess, the motion model's or the input odometry's (report.json: "
                   "registration.per_scan); give poses or odometry if they are wrong\n",
                   n, out.scans(), why.c_str());
    }
    // The scans' time, and the command's: the start-up before them and the map's final decision
    // after them take a fifth to a third of a short run (report.json `process`, the same values).
    const auto& pt = out.processTimes();
    if (pt.wall_s && pt.end_s)
      std::printf(
          "cleanmap: %zu scans in %.1f s, %.1f s in all (start-up %.1f s, the map's final "
          "decision and files %.1f s); results in %s\n",
          out.scans(), wall, *pt.wall_s, *out.startSeconds(), *pt.end_s, outdir.c_str());
    else
      std::printf("cleanmap: %zu scans in %.1f s; results in %s\n", out.scans(), wall,
                  outdir.c_str());
    if (const auto e = out.evaluation())
      std::printf(
          "cleanmap: moving class: precision %.3f, recall %.3f, IoU %.3f (%llu points evaluated)\n",
          e->precision(), e->recall(), e->iou(), (unsigned long long)e->evaluated());
    // Everything is published: the run ends here, without freeing its few hundred MB piece by
    // piece and running MRPT's libraries' finalizers (30-45 ms a run, doc/BENCHMARK.md).
    exitNow(0);
  } catch (const Interrupted& i) {
    if (progress_shown) std::fprintf(stderr, "\n");
    std::fprintf(stderr, "cleanmap: interrupted by %s; nothing written to %s\n",
                 i.sig == SIGINT ? "SIGINT" : "SIGTERM", outdir.c_str());
    return 128 + i.sig;
  } catch (const std::exception& e) {
    if (progress_shown) std::fprintf(stderr, "\n");
    std::cerr << "cleanmap: error: "
              << cleanmap::io::messageWithoutStaging(cleanmap::cli::errorLine(e), outdir,
                                                     "cleanmap")
              << '\n';
    return 1;
  }
  return 0;
}
