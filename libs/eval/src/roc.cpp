// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/eval/roc.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>

#include "cleanmap/core/error.h"
#include "cleanmap/eval/pictures.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/pipeline/laser_pipeline.h"

namespace cleanmap::eval {

std::vector<RocSetting> rocSweep(const std::string& gt_dir, const PipelineParams& base,
                                 const RocOptions& opt,
                                 const std::function<void(std::size_t, std::size_t)>& progress) {
  if (opt.sigma_r.empty() || opt.lambda_theta.empty())
    throw Error(gt_dir, "ROC sweep: empty parameter grid");
  for (double v : opt.sigma_r)
    if (!(v >= 0)) throw Error(gt_dir, "ROC sweep: sigma_r values must be >= 0");
  for (double v : opt.lambda_theta)
    if (!(v > 0)) throw Error(gt_dir, "ROC sweep: sigma_theta values must be > 0");
  io::KittiReadOptions ro;
  ro.scan.allow_empty = true;
  ro.load_images = false;
  auto seq = io::KittiSequence::open(gt_dir, ro);
  if (!seq.hasLabels()) throw Error(gt_dir, "no labels/ folder: the ROC sweep needs ground truth");
  if (!seq.hasPoses()) throw Error(gt_dir, "no poses: the laser pipeline needs them");
  const std::size_t first = static_cast<std::size_t>(std::max(0L, opt.first));
  const std::size_t last =
      opt.last < 0 ? seq.size() - 1 : std::min<std::size_t>(seq.size() - 1, std::size_t(opt.last));
  if (seq.size() == 0 || first > last) throw Error(gt_dir, "the scan range is empty");

  std::vector<RocSetting> out;
  const std::size_t total = opt.sigma_r.size() * opt.lambda_theta.size();
  for (double lt : opt.lambda_theta)
    for (double sr : opt.sigma_r) {
      PipelineParams p = base;
      p.ds.sigma_r = sr;
      p.ds.lambda_theta = lt;
      RocSetting s{sr, lt, {}};
      LaserPipeline pipe(p, [&](ScanResult&& r) {
        s.counts += compareLabels(r.labels, seq.loadLabels(r.index, r.labels.size()),
                                  seq.labelPath(r.index));
      });
      for (std::size_t i = first; i <= last; ++i) pipe.push(seq.frame(i));
      pipe.finish();
      out.push_back(s);
      if (progress) progress(out.size(), total);
    }
  return out;
}

void writeRoc(const std::string& dir, const std::string& sequence, const std::vector<RocSetting>& s,
              const PipelineParams& base) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(dir, "cannot create the output folder: " + ec.message());
  nlohmann::json j = nlohmann::json::array();
  for (const auto& r : s)
    j.push_back({{"sigma_r", r.sigma_r},
                 {"sigma_theta", r.lambda_theta},
                 {"tpr", r.tpr()},
                 {"fpr", r.fpr()},
                 {"precision", r.counts.precision()},
                 {"recall", r.counts.recall()},
                 {"iou", r.counts.iou()},
                 {"tp", r.counts.tp},
                 {"fp", r.counts.fp},
                 {"fn", r.counts.fn},
                 {"tn", r.counts.tn}});
  io::writeFileAtomic(dir + "/roc.json", [&](std::ostream& os) { os << j.dump(1) << '\n'; });

  std::map<double, RocCurve> curves;  // one per sigma_theta, points in sweep order of sigma_r
  RocCurvePoint marked{-1, -1};
  for (const auto& r : s) {
    auto& c = curves[r.lambda_theta];
    char label[64];
    std::snprintf(label, sizeof label, "sigma_theta %.4f", r.lambda_theta);
    c.label = label;
    c.points.push_back({r.fpr(), r.tpr()});
    if (std::abs(r.sigma_r - base.ds.sigma_r) < 1e-9 &&
        std::abs(r.lambda_theta - base.ds.lambda_theta) < 1e-9)
      marked = {r.fpr(), r.tpr()};
  }
  std::vector<RocCurve> list;
  for (auto& [k, c] : curves) list.push_back(std::move(c));
  writePng(dir + "/roc.png",
           rocPlot(list, marked, "ROC " + sequence + " (sigma_r varies along a curve)"));

  io::writeFileAtomic(dir + "/roc.md", [&](std::ostream& os) {
    os << "# ROC sweep: " << sequence
       << "\n\nLaser pipeline, default parameters except sigma_r and "
          "sigma_theta (= lambda_theta); DESIGN §5. Default marked *.\n\n"
          "| sigma_theta (rad) | sigma_r (m) | TPR (recall) | FPR | precision | IoU "
          "|\n|---|---|---|---|---|---|\n";
    char b[256];
    for (const auto& r : s) {
      const bool def = std::abs(r.sigma_r - base.ds.sigma_r) < 1e-9 &&
                       std::abs(r.lambda_theta - base.ds.lambda_theta) < 1e-9;
      std::snprintf(b, sizeof b, "| %.4f | %.2f%s | %.3f | %.4f | %.3f | %.3f |\n", r.lambda_theta,
                    r.sigma_r, def ? " *" : "", r.tpr(), r.fpr(), r.counts.precision(),
                    r.counts.iou());
      os << b;
    }
    os << "\n![ROC](roc.png)\n";
  });
}

}  // namespace cleanmap::eval
