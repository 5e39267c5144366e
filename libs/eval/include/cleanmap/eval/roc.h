// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §5 ROC: the laser pipeline over a grid of sigma_r x sigma_theta (= lambda_theta), TPR and
// FPR of the moving class per setting, like the paper's ROC figure.
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "cleanmap/core/metrics.h"
#include "cleanmap/core/params.h"

namespace cleanmap::eval {

struct RocSetting {
  double sigma_r = 0, lambda_theta = 0;
  MosCounts counts;
  double tpr() const { return counts.recall(); }
  double fpr() const {
    return counts.fp + counts.tn ? double(counts.fp) / double(counts.fp + counts.tn) : 0.0;
  }
};

struct RocOptions {
  std::vector<double> sigma_r{0.10, 0.15, 0.20, 0.30, 0.45};
  std::vector<double> lambda_theta{0.0035, 0.0061, 0.0088};
  long first = 0, last = -1;
};

/// Runs the pipeline (base parameters, sigma_r and lambda_theta replaced) once per setting over
/// the labelled KITTI folder `gt_dir`. `progress(done, total)` after each setting.
std::vector<RocSetting> rocSweep(
    const std::string& gt_dir, const PipelineParams& base, const RocOptions& opt,
    const std::function<void(std::size_t, std::size_t)>& progress = {});

/// roc.md (table), roc.json and roc.png (one curve per lambda_theta; `base`'s setting marked)
/// into `dir`, atomically.
void writeRoc(const std::string& dir, const std::string& sequence, const std::vector<RocSetting>& s,
              const PipelineParams& base);

}  // namespace cleanmap::eval
