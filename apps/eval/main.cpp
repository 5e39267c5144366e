// SPDX-License-Identifier: BSD-3-Clause
// cleanmap-eval: scores a result against a labelled sequence (SPEC §5), runs the ROC sweep, and
// sums reports into one table.
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>

#include "cleanmap/core/error.h"
#include "cleanmap/eval/evaluate.h"
#include "cleanmap/eval/roc.h"
#include "cleanmap/io/config.h"

namespace {

constexpr const char* kUsage = R"(usage:
  cleanmap-eval GT_DIR RESULT [--first N --last M] [--labels DIR] [--report DIR] [--json]
                [--radius R] [--crop TAU]
  cleanmap-eval roc GT_DIR -o DIR [--sigma-r LIST] [--sigma-theta LIST] [-c INI] [--threads N]
                [--first N --last M]
  cleanmap-eval summary REPORT.json...

Scores moving-object removal against ground truth (SPEC.md §5).
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
--crop TAU     ground-truth map points used: |x|,|y|,|z| <= TAU in the sensor frame (default: the
               run's crop from params.ini, else 30; 0 = all)
Measures: per point precision / recall / IoU of the moving class (paper Table I); per object
Detected (f >= 0.9) / Partially detected (0.1 <= f < 0.9) (Table II, needs objects.json);
DynamicMap SA, DA, AA = sqrt(SA DA), HA = 2 SA DA / (SA + DA); runtime from report.json.

roc            runs the laser pipeline per (sigma_r, sigma_theta) of the grid and writes roc.md,
               roc.json, roc.png into DIR. LIST: comma-separated values
               (defaults 0.10,0.15,0.20,0.30,0.45 m and 0.0035,0.0061,0.0088 rad)
summary        one Markdown table of evaluation report.json / --json files, with an overall row
Exit status: 0 ok, 1 error (one line on stderr), 2 bad command line.
)";

[[noreturn]] void usageError(const std::string& msg) {
  std::cerr << "cleanmap-eval: " << msg << " (see --help)\n";
  std::exit(2);
}

double toDouble(const std::string& flag, const std::string& v) {
  try {
    std::size_t used = 0;
    const double x = std::stod(v, &used);
    if (used == v.size() && x >= 0) return x;
  } catch (const std::exception&) {
  }
  usageError(flag + " needs a non-negative number, got '" + v + "'");
}

long toLong(const std::string& flag, const std::string& v) {
  try {
    std::size_t used = 0;
    const long x = std::stol(v, &used);
    if (used == v.size() && x >= 0) return x;
  } catch (const std::exception&) {
  }
  usageError(flag + " needs a non-negative integer, got '" + v + "'");
}

std::vector<double> toList(const std::string& flag, const std::string& v) {
  std::vector<double> out;
  std::stringstream ss(v);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(toDouble(flag, item));
  if (out.empty()) usageError(flag + " needs a comma-separated list");
  return out;
}

int runSummary(int argc, char** argv) {
  std::vector<std::string> files;
  for (int i = 2; i < argc; ++i) files.emplace_back(argv[i]);
  if (files.empty()) usageError("summary needs report JSON files");
  std::cout << cleanmap::eval::summaryTable(files);
  return 0;
}

int runRoc(int argc, char** argv) {
  std::string gt, out, config;
  cleanmap::eval::RocOptions opt;
  long threads = -1;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usageError(a + " needs a value");
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "-o" || a == "--output") out = value();
    else if (a == "-c" || a == "--config") config = value();
    else if (a == "--sigma-r") opt.sigma_r = toList(a, value());
    else if (a == "--sigma-theta") opt.lambda_theta = toList(a, value());
    else if (a == "--threads") threads = toLong(a, value());
    else if (a == "--first") opt.first = toLong(a, value());
    else if (a == "--last") opt.last = toLong(a, value());
    else if (!a.empty() && a[0] == '-') usageError("unknown option '" + a + "'");
    else if (gt.empty()) gt = a;
    else usageError("unexpected argument '" + a + "'");
  }
  if (gt.empty() || out.empty()) usageError("roc needs GT_DIR and -o DIR");
  if (threads == 0) usageError("--threads must be >= 1");
  if (opt.last >= 0 && opt.last < opt.first) usageError("--last must be >= --first");
  cleanmap::PipelineParams base;
  if (!config.empty()) cleanmap::io::loadParams(config, base);
  if (threads > 0) base.threads = static_cast<int>(threads);
  const auto res = cleanmap::eval::rocSweep(gt, base, opt, [](std::size_t d, std::size_t t) {
    std::fprintf(stderr, "\rcleanmap-eval roc: %zu/%zu settings   ", d, t);
  });
  std::fprintf(stderr, "\n");
  std::string seq = gt;
  while (!seq.empty() && seq.back() == '/') seq.pop_back();
  seq = seq.substr(seq.find_last_of('/') + 1);
  cleanmap::eval::writeRoc(out, seq, res, base);
  std::printf("cleanmap-eval roc: %zu settings; table %s/roc.md, plot %s/roc.png\n", res.size(), out.c_str(), out.c_str());
  return 0;
}

int runEval(int argc, char** argv) {
  std::string gt, result, report;
  std::optional<std::string> labels;
  cleanmap::eval::EvalOptions opt;
  bool json = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usageError(a + " needs a value");
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--first") opt.first = toLong(a, value());
    else if (a == "--last") opt.last = toLong(a, value());
    else if (a == "--labels") labels = value();
    else if (a == "--report") report = value();
    else if (a == "--json") json = true;
    else if (a == "--radius") {
      opt.radius = toDouble(a, value());
      if (opt.radius <= 0) usageError("--radius must be > 0");
    } else if (a == "--crop") opt.crop_tau = toDouble(a, value());
    else if (!a.empty() && a[0] == '-') usageError("unknown option '" + a + "'");
    else if (gt.empty()) gt = a;
    else if (result.empty()) result = a;
    else usageError("unexpected argument '" + a + "'");
  }
  if (gt.empty() || result.empty()) usageError("need GT_DIR and RESULT");
  if (opt.last >= 0 && opt.last < opt.first) usageError("--last must be >= --first");
  opt.pictures_dir = report;
  const auto in = cleanmap::eval::ResultInput::fromPath(result, labels);
  const auto rep = cleanmap::eval::evaluate(gt, in, opt);
  if (!report.empty()) cleanmap::eval::writeReport(report, rep);
  if (json) {
    std::cout << cleanmap::eval::toJson(rep) << '\n';
    return 0;
  }
  std::printf("%s: %zu scans\n", rep.sequence.c_str(), rep.scans);
  if (rep.mos)
    std::printf("  moving class: precision %.3f, recall %.3f, IoU %.3f (%llu points scored)\n",
                rep.mos->precision(), rep.mos->recall(), rep.mos->iou(), (unsigned long long)rep.mos->evaluated());
  if (rep.objects) {
    int d = 0, p = 0, m = 0;
    for (const auto& o : *rep.objects) {
      if (!o.moving_points) continue;
      const auto g = o.grade();
      d += g == cleanmap::ObjectGrade::kDetected;
      p += g == cleanmap::ObjectGrade::kPartial;
      m += g == cleanmap::ObjectGrade::kMissed;
    }
    std::printf("  objects: %d detected, %d partially detected, %d missed\n", d, p, m);
  }
  if (rep.map)
    std::printf("  clean map: SA %.4f, DA %.4f, AA %.4f, HA %.4f\n", rep.map->sa(), rep.map->da(), rep.map->aa(),
                rep.map->ha());
  if (rep.runtime && !rep.runtime->stages.empty())
    std::printf("  runtime: median %.1f ms/scan, p95 %.1f ms/scan (%d threads)\n", rep.runtime->stages[0].median_ms,
                rep.runtime->stages[0].p95_ms, rep.runtime->threads);
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
    std::cerr << "cleanmap-eval: error: " << e.what() << '\n';
    return 1;
  }
}
