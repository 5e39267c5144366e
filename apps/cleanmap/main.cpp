// SPDX-License-Identifier: BSD-3-Clause
// cleanmap: moving-object removal over a KITTI folder or an MRPT rawlog (DESIGN §2, §4).
#include <unistd.h>
#include <chrono>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>

#include "../common/cli.h"
#include "cleanmap/core/error.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/io/output.h"
#include "cleanmap/mrpt/input.h"
#include "cleanmap/mrpt/outputs.h"
#include "cleanmap/pipeline/laser_pipeline.h"

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

constexpr const char* kUsage = R"(usage: cleanmap INPUT -o OUTDIR [options]

Finds the moving points in a sequence of lidar scans (Dempster-Shafer occupancy over a window of
K past and K future scans, after ground removal; doc/DESIGN.md §2) and writes, into OUTDIR:
  labels/<stem>.label   uint32 per original point: 251 moving, 9 static, 40 ground, 0 not classified
  static_map.ply/.pcd   compact static map (duplicates of the recent map left out), world frame,
                        RGB by height above the sensor
  static_map_full.ply   every static point (ground included), world frame, RGB by height
  dynamic.ply/.pcd      the moving points, world frame, red
  static_map.3Dscene    for SceneViewer3D: static map (one point per 0.1 m voxel), moving
                        points in red, trajectory (doc/MRPT.md)
  static_map.simplemap  every scan without its moving points, with its pose (MRPT CSimpleMap)
  cleaned.rawlog        per scan: CObservationRobotPose + CObservationPointCloud without the
                        moving points, for any MRPT SLAM or localization
  labelled.rawlog       per scan: pose + the scan coloured by label (RawLogViewer; doc/FORMATS.md)
  poses.txt             lidar poses used (KITTI 3x4 rows); params.ini: the parameters of the run
  report.json, report.md  counts, time per stage, and precision/recall/IoU when INPUT has labels

INPUT                a KITTI odometry/SemanticKITTI or raw folder, or an MRPT .rawlog
-o, --output DIR     output folder. The run is written beside it and moved into place when
                     complete: an earlier cleanmap run there is replaced as a whole; an
                     interrupted or failed run leaves DIR as it was
--force              replace DIR even if it is a non-empty folder that holds no cleanmap run
-c, --config FILE    ini file of parameters (see config/cleanmap.ini; unknown keys are errors)
--threads N          worker threads for the moving-point test (default 2; results do not depend on it)
--seed S             seed of the octree sampling (default 42; same seed, same output bit for bit)
--first N, --last M  process scans N..M only (indices in the input, inclusive)
--poses SOURCE       given: the input's poses (KITTI poses.txt / OXTS, rawlog CObservationRobotPose);
                     gicp: GICP scan-to-map odometry (DESIGN §2.1; a given first pose anchors it);
                     refine: GICP started from each given pose. Default: given when the first
                     scan has a pose, gicp otherwise. report.json says what each scan used.
--no-mrpt-outputs    skip the .3Dscene, .simplemap and the two rawlogs
--viewer-voxel M     voxel of the .3Dscene's decimation, metres (default 0.1; files keep every point)
--quiet              no progress line (there is none when stderr is not a terminal)
Scans without any valid point (0-byte .bin, all NaN) are kept as empty scans: labelled 0,
counted in report.json (empty_scans) and in one warning line.
Exit status: 0 done, 1 error (one line naming the file), 2 bad command line, 130 / 143
interrupted by SIGINT / SIGTERM (nothing written to DIR).
--help               this text
)";

}  // namespace

int main(int argc, char** argv) {
  std::string input, outdir, config, poses = "auto";
  long threads = -1, first = 0, last = -1;
  long long seed = -1;
  bool quiet = false, progress_shown = false, force = false, mrpt_outputs = true;
  double viewer_voxel = 0.1;
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
  if (!(viewer_voxel > 0)) args.fail("--viewer-voxel must be > 0");

  quiet = quiet || !::isatty(STDERR_FILENO);  // progress lines only on a terminal, not in logs
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  try {
    {  // never write into the input: its labels/ would be replaced by ours
      std::error_code ec;
      if (std::filesystem::exists(outdir, ec) && std::filesystem::equivalent(outdir, input, ec))
        throw cleanmap::Error(outdir, "the output folder is the input folder; choose another -o");
    }
    cleanmap::PipelineParams params;
    if (!config.empty()) cleanmap::io::loadParams(config, params);
    if (threads > 0) params.threads = static_cast<int>(threads);
    if (seed >= 0) params.seed = static_cast<uint64_t>(seed);
    params.poses = poses == "given"    ? cleanmap::PoseSource::kGiven
                   : poses == "gicp"   ? cleanmap::PoseSource::kGicp
                   : poses == "refine" ? cleanmap::PoseSource::kRefine
                                       : cleanmap::PoseSource::kAuto;

    cleanmap::mrpt::InputOptions in_opts;
    in_opts.allow_empty_scans = true;  // counted in the report
    in_opts.load_images = false;       // the laser pipeline does not use them
    auto src = cleanmap::mrpt::openInput(input, in_opts);
    const auto* kitti = dynamic_cast<const cleanmap::io::KittiSequence*>(src.get());
    const bool evaluate = kitti && kitti->hasLabels();

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
      mrpt_out.emplace(out.staging(), mo);
    }
    std::size_t seen = 0, empty = 0;
    const auto t0 = std::chrono::steady_clock::now();
    const auto total = src->sizeHint();
    cleanmap::LaserPipeline pipeline(params, [&](cleanmap::ScanResult&& r) {
      checkSignal();
      std::optional<cleanmap::MosCounts> eval;
      if (evaluate)
        eval = cleanmap::compareLabels(r.labels, kitti->loadLabels(r.index, r.labels.size()),
                                       kitti->labelPath(r.index));
      out.write(r, eval);
      if (mrpt_out) mrpt_out->write(std::move(r));
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
    pipeline.keepScans(mrpt_outputs);  // the rawlogs are made from each scan's points
    while (auto f = src->next()) {
      checkSignal();
      const long idx = static_cast<long>(f->index);
      ++seen;
      if (idx < first) continue;
      if (last >= 0 && idx > last) break;
      empty += f->scan.empty();
      pipeline.push(std::move(*f));
    }
    pipeline.finish();
    checkSignal();
    if (out.scans() == 0)
      throw cleanmap::Error(input, "no scans in the requested range: the input has " +
                                       std::to_string(seen) + " scans (--first " +
                                       std::to_string(first) + ")");
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (mrpt_out) {
      mrpt_out->finish();
      out.addOutputTime("mrpt", mrpt_out->writeMs());
    }
    out.finish(wall);
    if (progress_shown) std::fprintf(stderr, "\n");
    if (empty)
      std::fprintf(stderr,
                   "cleanmap: warning: %zu empty scans (no valid point) kept, labelled 0 "
                   "(report.json: empty_scans)\n",
                   empty);
    std::printf("cleanmap: %zu scans in %.1f s; results in %s\n", out.scans(), wall,
                outdir.c_str());
    if (const auto e = out.evaluation())
      std::printf(
          "cleanmap: moving class: precision %.3f, recall %.3f, IoU %.3f (%llu points evaluated)\n",
          e->precision(), e->recall(), e->iou(), (unsigned long long)e->evaluated());
  } catch (const Interrupted& i) {
    if (progress_shown) std::fprintf(stderr, "\n");
    std::fprintf(stderr, "cleanmap: interrupted by %s; nothing written to %s\n",
                 i.sig == SIGINT ? "SIGINT" : "SIGTERM", outdir.c_str());
    return 128 + i.sig;
  } catch (const std::exception& e) {
    if (progress_shown) std::fprintf(stderr, "\n");
    std::cerr << "cleanmap: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
