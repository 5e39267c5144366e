// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-eval: scores a result against a labelled sequence (DESIGN §5), runs the ROC sweep, and
// sums reports into one table.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "../common/cli.h"
#include "cleanmap/core/error.h"
#include "cleanmap/eval/evaluate.h"
#include "cleanmap/eval/roc.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/maps/map_config.h"

namespace {

namespace fs = std::filesystem;

// The folders written here (--report, roc -o) are written as a whole (io::StagedFolder): an error
// or a signal leaves the earlier folder as it was, and a rerun over fewer scans leaves no pictures
// of the earlier one. Only an earlier folder of the same kind is replaced.
constexpr const char* kStagingTag = "cleanmap-eval";
std::string g_staged;  // the folder being written, so that errors name its own paths

bool firstLineStarts(const fs::path& file, const std::string& prefix) {
  std::ifstream in(file);
  std::string line;
  return in && std::getline(in, line) && line.rfind(prefix, 0) == 0;
}

constexpr const char* kUsage = R"(usage:
  cleanmap-eval GT_DIR RESULT [--first N --last M] [--labels DIR] [--report DIR] [--json]
                [--radius R] [--map-range M] [--crop TAU|run] [--camera-fov]
  cleanmap-eval roc GT_DIR -o DIR [--sigma-r LIST] [--sigma-theta LIST] [-c INI] [--threads N]
                [--first N --last M]
  cleanmap-eval summary REPORT.json...

Scores moving-object removal against ground truth (DESIGN §5).
GT_DIR         a labelled sequence folder (velodyne/, labels/, poses.txt, optional objects.json),
               as in ../shared/data or SemanticKITTI
RESULT         a cleanmap output folder (labels/, static_map_full.ply, report.json, params.ini)
               or any tool's clean map as .ply / .pcd (world frame of GT_DIR's poses)
--labels DIR   per-scan <stem>.label files of the result (SemanticKITTI-MOS ids: 251 moving)
--first/--last scan range, inclusive (indices in GT_DIR)
--report DIR   write report.md, report.json and pictures (bird's-eye view per scan: TP red,
               FP orange, FN blue, static grey; clean-map overview) into DIR
--json         print one JSON object (precision, recall, iou with labels; SA, DA, AA, HA with a
               map; counts, objects, runtime) instead of the text summary
--radius R     DynamicMap "kept" distance, metres (default 0.05)
--map-range M  ground truth of the map scores: the labelled points within M metres horizontally
               of their scan's sensor (default 50, the DynamicMap benchmark's, whatever the run's
               crop: a map that covers less scores less; 0 = all)
--crop TAU|run also keep only |x|,|y|,|z| <= TAU in the sensor frame; `run`: the run's own crop
               (filter.crop_tau of its params.ini)
--camera-fov   per-point and object measures over the points in the camera's view only (in
               front of it, inside image_2; calib.txt P2 and Tr), as the paper's Table I scores
               its image masks; the map scores stay whole
Measures: per point precision / recall / IoU of the moving class (paper Table I); per object
Detected (f >= 0.9) / Partially detected (0.1 <= f < 0.9) (Table II, needs objects.json);
DynamicMap SA, DA, AA = sqrt(SA DA), HA = 2 SA DA / (SA + DA); runtime from report.json.

roc            runs the laser pipeline per (sigma_r, sigma_theta) of the grid and writes roc.md,
               roc.json, roc.png into DIR. LIST: comma-separated values
               (defaults 0.10,0.15,0.20,0.30,0.45 m and 0.0035,0.0061,0.0088 rad)
summary        one Markdown table of evaluation report.json / --json files, with an overall row
Exit status: 0 ok, 1 error (one line on stderr), 2 bad command line.
)";

int runSummary(int argc, char** argv) {
  std::vector<std::string> files;
  for (int i = 2; i < argc; ++i) files.emplace_back(argv[i]);
  if (files.empty())
    cleanmap::cli::Args("cleanmap-eval", argc, argv).fail("summary needs report JSON files");
  std::cout << cleanmap::eval::summaryTable(files);
  return 0;
}

int runRoc(int argc, char** argv) {
  std::string gt, out, config;
  cleanmap::eval::RocOptions opt;
  long threads = -1;
  cleanmap::cli::Args args("cleanmap-eval", argc, argv, 2);
  while (!args.done()) {
    const std::string a = args.next();
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "-o" || a == "--output")
      out = args.value(a);
    else if (a == "-c" || a == "--config")
      config = args.value(a);
    else if (a == "--sigma-r")
      opt.sigma_r = args.numbers(a);
    else if (a == "--sigma-theta")
      opt.lambda_theta = args.numbers(a);
    else if (a == "--threads")
      threads = args.integer(a, 1);
    else if (a == "--first")
      opt.first = args.integer(a);
    else if (a == "--last")
      opt.last = args.integer(a);
    else if (!a.empty() && a[0] != '-' && gt.empty())
      gt = a;
    else
      args.unexpected(a);
  }
  if (gt.empty() || out.empty()) args.fail("roc needs GT_DIR and -o DIR");
  if (opt.last >= 0 && opt.last < opt.first) args.fail("--last must be >= --first");
  cleanmap::PipelineParams base;
  if (!config.empty()) base = cleanmap_maps::loadPipelineParams(config);  // MRPT or flat ini
  if (threads > 0) base.threads = static_cast<int>(threads);
  const auto isRoc = [](const std::string& d) {
    return firstLineStarts(fs::path(d) / "roc.md", "# ROC sweep");
  };
  cleanmap::io::requireOutsideInput(out, gt, isRoc, "-o");
  cleanmap::io::requireReplaceableFolder(out, isRoc, "ROC sweep of cleanmap-eval (no roc.md)",
                                         "-o");
  cleanmap::io::StagedFolder staged(out, kStagingTag);
  g_staged = out;
  const auto res = cleanmap::eval::rocSweep(gt, base, opt, [](std::size_t d, std::size_t t) {
    std::fprintf(stderr, "\rcleanmap-eval roc: %zu/%zu settings   ", d, t);
  });
  std::fprintf(stderr, "\n");
  std::string seq = gt;
  while (!seq.empty() && seq.back() == '/') seq.pop_back();
  seq = seq.substr(seq.find_last_of('/') + 1);
  cleanmap::eval::writeRoc(staged.path(), seq, res, base);
  staged.publish();
  std::printf("cleanmap-eval roc: %zu settings; table %s/roc.md, plot %s/roc.png\n", res.size(),
              out.c_str(), out.c_str());
  return 0;
}

int runEval(int argc, char** argv) {
  std::string gt, result, report;
  std::optional<std::string> labels;
  cleanmap::eval::EvalOptions opt;
  bool json = false;
  cleanmap::cli::Args args("cleanmap-eval", argc, argv);
  while (!args.done()) {
    const std::string a = args.next();
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--first")
      opt.first = args.integer(a);
    else if (a == "--last")
      opt.last = args.integer(a);
    else if (a == "--labels")
      labels = args.value(a);
    else if (a == "--report")
      report = args.value(a);
    else if (a == "--json")
      json = true;
    else if (a == "--radius") {
      opt.radius = args.number(a);
      if (opt.radius <= 0) args.fail("--radius must be > 0");
    } else if (a == "--map-range") {
      opt.map_range = args.number(a);
    } else if (a == "--camera-fov") {
      opt.camera_fov = true;
    } else if (a == "--crop") {
      const std::string v = args.value(a);
      if (v == "run")
        opt.run_crop = true;
      else
        opt.crop_tau = args.toNumber(a, v);
    } else if (!a.empty() && a[0] != '-' && gt.empty())
      gt = a;
    else if (!a.empty() && a[0] != '-' && result.empty())
      result = a;
    else
      args.unexpected(a);
  }
  if (gt.empty() || result.empty()) args.fail("need GT_DIR and RESULT");
  if (opt.last >= 0 && opt.last < opt.first) args.fail("--last must be >= --first");
  const auto in = cleanmap::eval::ResultInput::fromPath(result, labels);
  std::unique_ptr<cleanmap::io::StagedFolder> staged;
  if (!report.empty()) {
    const auto isReport = [](const std::string& d) {
      return firstLineStarts(fs::path(d) / "report.md", "# cleanmap evaluation");
    };
    for (const std::string& read : {gt, result, labels.value_or("")})
      cleanmap::io::requireOutsideInput(report, read, isReport, "--report");
    cleanmap::io::requireReplaceableFolder(
        report, isReport, "report of cleanmap-eval (no report.md of one)", "--report");
    staged = std::make_unique<cleanmap::io::StagedFolder>(report, kStagingTag);
    g_staged = report;
    opt.pictures_dir = staged->path();
  }
  const auto rep = cleanmap::eval::evaluate(gt, in, opt);
  if (staged) {
    cleanmap::eval::writeReport(staged->path(), rep);
    staged->publish();
  }
  if (json) {
    std::cout << cleanmap::eval::toJson(rep) << '\n';
    return 0;
  }
  std::printf("%s: %zu scans\n", rep.sequence.c_str(), rep.scans);
  if (rep.mos)
    std::printf("  moving class: precision %.3f, recall %.3f, IoU %.3f (%llu points scored%s)\n",
                rep.mos->precision(), rep.mos->recall(), rep.mos->iou(),
                (unsigned long long)rep.mos->evaluated(),
                rep.camera_fov ? ", in the camera's view" : "");
  if (rep.objects) {
    const auto g = rep.gradeCounts();
    std::printf("  objects: %d detected, %d partially detected, %d missed\n", g.detected, g.partial,
                g.missed);
  }
  if (rep.map)
    std::printf("  clean map: SA %.4f, DA %.4f, AA %.4f, HA %.4f\n", rep.map->sa(), rep.map->da(),
                rep.map->aa(), rep.map->ha());
  if (rep.runtime && !rep.runtime->stages.empty())
    std::printf("  runtime: median %.1f ms/scan, p95 %.1f ms/scan (%d threads)\n",
                rep.runtime->stages[0].median_ms, rep.runtime->stages[0].p95_ms,
                rep.runtime->threads);
  if (!report.empty()) std::printf("  report: %s/report.md\n", report.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string cmd = argc > 1 ? argv[1] : "";
    if (cmd == "summary") return runSummary(argc, argv);
    if (cmd == "roc") return runRoc(argc, argv);
    return runEval(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "cleanmap-eval: error: "
              << (g_staged.empty() ? cleanmap::cli::errorLine(e)
                                   : cleanmap::io::messageWithoutStaging(
                                         cleanmap::cli::errorLine(e), g_staged, kStagingTag))
              << '\n';
    return 1;
  }
}
